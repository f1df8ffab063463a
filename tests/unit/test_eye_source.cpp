// SPDX-License-Identifier: Apache-2.0
// The eye pipeline as a daemon source (eye/eye_source.h) and the synthetic-eye frame source
// (sim/synthetic_eye_frames.h): detection on rendered frames, the factory calibration, blinks,
// frame-source health, never NaN, real-time pacing, and the daemon's synthetic-eye spec.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <deque>
#include <limits>
#include <vector>

#include "daemon.h"
#include "sources/source_table.h"
#include "eye/eye_source.h"
#include "sim/synthetic_eye.h"
#include "sim/synthetic_eye_frames.h"
#include "fovea/protocol/clock.h"

using namespace fovea;
using namespace fovea::trackerd;
using namespace fovea::trackerd::eye;

namespace {

// Frames handed over one by one, with a health state the test sets.
class FakeFrames final : public FrameSource {
 public:
  std::deque<EyeFrame> frames;
  FrameSourceStatus st{"fake-eye-camera 320x240", true, {}, 0, 0};
  bool end_when_empty = false;

  FrameSourceStatus status() const override { return st; }
  std::optional<EyeFrame> next(int) override {
    if (frames.empty()) return std::nullopt;
    EyeFrame f = std::move(frames.front());
    frames.pop_front();
    ++st.frames;
    return f;
  }
  bool ended() const override { return end_when_empty && frames.empty(); }
};

struct Rendered {
  EyeFrame frame;
  protocol::Degrees gaze;
  bool closed = false;
};

// Frames of the synthetic eye looking at the given screen points (degrees), 120 Hz.
std::vector<Rendered> render(SyntheticEye& eye, const protocol::DisplayGeometry& display,
                             const std::vector<protocol::Degrees>& gazes, double openness = 1.0) {
  std::vector<Rendered> out;
  std::int64_t t = 1'000'000'000;
  std::uint64_t seq = 0;
  for (const auto& g : gazes) {
    const EyeRotation r = screen_to_eye_rotation(display, g);
    EyeTruth truth;
    Rendered x;
    x.frame.image = eye.render(r.yaw_deg, r.pitch_deg, openness, &truth);
    x.frame.time_ns = t;
    x.frame.sequence = seq++;
    x.gaze = g;
    x.closed = truth.closed;
    out.push_back(std::move(x));
    t += 8'333'333;
  }
  return out;
}

// Screen points spread over the screen (not at the very edges), deterministic.
std::vector<protocol::Degrees> screen_points(const protocol::DisplayGeometry& display, int n) {
  std::vector<protocol::Degrees> out;
  for (int i = 0; i < n; ++i) {
    const double u = 0.1 + 0.8 * std::fmod(0.618034 * i, 1.0), v = 0.1 + 0.8 * std::fmod(0.754878 * i + 0.3, 1.0);
    out.push_back(protocol::normalized_to_degrees(display, {u, v}));
  }
  return out;
}

double median(std::vector<double> v) {
  if (v.empty()) return std::numeric_limits<double>::infinity();
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
  return v[v.size() / 2];
}

bool all_finite(const protocol::GazeSample& s) {
  for (const float f : {s.x, s.y, s.x_deg, s.y_deg, s.confidence, s.angular_velocity_deg_s, s.right.pupil_x_px,
                        s.right.pupil_y_px, s.right.pupil_diameter_mm, s.right.pupil_glint_x_px,
                        s.right.pupil_glint_y_px, s.left.pupil_x_px, s.left.pupil_y_px}) {
    if (!std::isfinite(f)) return false;
  }
  return true;
}

struct Pipeline {
  protocol::DisplayGeometry display;
  SyntheticEyeOptions eye_options;
  std::unique_ptr<SyntheticEye> eye;
  FakeFrames* frames = nullptr;
  std::unique_ptr<EyePipelineSource> source;

  explicit Pipeline(bool with_map, SyntheticEyeOptions o = {}, EyeSide side = EyeSide::Right) : eye_options(o) {
    eye = std::make_unique<SyntheticEye>(o);
    auto f = std::make_unique<FakeFrames>();
    frames = f.get();
    EyePipelineOptions po;
    po.detector.leds = o.leds;
    po.eye = side;
    po.display = display;
    po.nominal_rate_hz = 120;
    po.mm_per_px = pupil_mm_per_px(*eye);
    po.detector.blink_aspect = factory_blink_aspect(*eye, display);
    if (with_map) po.map = factory_pupil_glint_map(fit_factory_map(*eye, display), display);
    source = std::make_unique<EyePipelineSource>(std::move(f), po);
  }
  void feed(const std::vector<Rendered>& r) {
    for (const auto& x : r) frames->frames.push_back(x.frame);
  }
  protocol::GazeSample next() {
    auto item = source->next();
    EXPECT_TRUE(item.has_value());
    if (!item) return {};
    EXPECT_TRUE(std::holds_alternative<protocol::GazeSample>(*item));
    return std::get<protocol::GazeSample>(*item);
  }
};

}  // namespace

TEST(EyeRotation, ScreenToEyeAndBack) {
  const protocol::DisplayGeometry display;
  for (const protocol::Degrees g : {protocol::Degrees{0, 0}, protocol::Degrees{20, -12}, protocol::Degrees{-7, 11}}) {
    const EyeRotation r = screen_to_eye_rotation(display, g);
    const protocol::Degrees back = eye_rotation_to_screen(display, r);
    EXPECT_NEAR(back.x, g.x, 1e-9);
    EXPECT_NEAR(back.y, g.y, 1e-9);
    EXPECT_NEAR(r.yaw_deg, g.x, 1e-9);  // Fick: yaw about the vertical axis first is the horizontal screen angle
  }
  // Looking diagonally, the pitch is smaller than the vertical screen angle (the point is farther away).
  const EyeRotation r = screen_to_eye_rotation(display, {20, 12});
  EXPECT_LT(r.pitch_deg, 12);
  EXPECT_GT(r.pitch_deg, 10);
}

TEST(SyntheticEyeFactoryMap, ModelErrorIsAFractionOfADegree) {
  const protocol::DisplayGeometry display;
  SyntheticEye eye{SyntheticEyeOptions{}};
  const calib::Poly2Map map = fit_factory_map(eye, display);
  EXPECT_EQ(map.points, 81u);
  EXPECT_LT(map.condition, 100) << map.describe();
  EXPECT_LT(map.rms_residual, 0.5) << map.describe();  // degrees of eye rotation
  // Between the grid points too: exact pupil-glint vectors, mapped, against the gaze. The rest is
  // the quadratic's model error (see synthetic_eye_frames.h).
  const PupilGlintMap pg = factory_pupil_glint_map(map, display);
  double sum = 0, worst = 0;
  const auto points = screen_points(display, 200);
  for (const auto& g : points) {
    const EyeRotation r = screen_to_eye_rotation(display, g);
    const EyeTruth t = eye.project(r.yaw_deg, r.pitch_deg);
    const protocol::Normalized n = pg.to_screen(t.pupil_glint);
    const double e = protocol::angle_between_deg(protocol::normalized_to_degrees(display, n), g);
    sum += e;
    worst = std::max(worst, e);
  }
  EXPECT_LT(sum / static_cast<double>(points.size()), 0.4);
  EXPECT_LT(worst, 1.2);
  EXPECT_FALSE(std::isfinite(pg.to_screen({1e6, 0}).x)) << "a wild vector must not give a screen point";
  const double s = pupil_mm_per_px(eye);
  EXPECT_GT(s, 0.01);
  EXPECT_LT(s, 1.0);
  const double blink = factory_blink_aspect(eye, display);
  EXPECT_GT(blink, 0.4);
  EXPECT_LE(blink, 0.7);
}

TEST(EyePipelineSource, CleanFramesGivePupilDataAndGazeWithinADegree) {
  Pipeline p(true);
  const auto gazes = screen_points(p.display, 60);
  const auto frames = render(*p.eye, p.display, gazes);
  p.feed(frames);
  std::vector<double> errors;
  std::size_t pupils = 0, valid = 0;
  for (const auto& f : frames) {
    const protocol::GazeSample s = p.next();
    ASSERT_TRUE(all_finite(s));
    EXPECT_EQ(s.tracker_time_ns, f.frame.time_ns);
    EXPECT_EQ(s.left.flags, 0) << "only the configured (right) eye is filled";
    if (s.right.flags & protocol::kEyePupilValid) {
      ++pupils;
      EXPECT_GT(s.right.pupil_x_px, 0);
      EXPECT_LT(s.right.pupil_x_px, 320);
      EXPECT_GT(s.right.pupil_diameter_mm, 3.0f);  // the model's 4 mm pupil, seen obliquely
      EXPECT_LT(s.right.pupil_diameter_mm, 5.0f);
    }
    if (s.flags & protocol::kGazeValid) {
      ++valid;
      EXPECT_NE(s.right.flags & protocol::kEyeGlintValid, 0);
      errors.push_back(protocol::angle_between_deg({s.x_deg, s.y_deg}, f.gaze));
      EXPECT_GT(s.confidence, 0.0f);
    }
  }
  EXPECT_GE(pupils, frames.size() * 95 / 100);
  EXPECT_GE(valid, frames.size() * 90 / 100);
  const double med = median(errors);
  EXPECT_LT(med, 1.0) << "median gaze error " << med << " deg";
  std::printf("clean frames: %zu of %zu with valid gaze, median error %.3f deg\n", valid, frames.size(), med);
  const auto c = p.source->counts();
  EXPECT_EQ(c.frames, frames.size());
  EXPECT_EQ(c.gaze, valid);
  EXPECT_NE(p.source->status_detail().find(std::to_string(frames.size()) + " frames"), std::string::npos)
      << p.source->status_detail();
}

TEST(EyePipelineSource, BlinksGiveInvalidGazeHeldAtTheLastPosition) {
  Pipeline p(true);
  const auto open = render(*p.eye, p.display, {{5, 3}, {5, 3}, {5, 3}});
  const auto closed = render(*p.eye, p.display, {{5, 3}, {5, 3}, {5, 3}, {5, 3}}, 0.0);
  p.feed(open);
  p.feed(closed);
  protocol::GazeSample last_valid;
  for (std::size_t i = 0; i < open.size(); ++i) last_valid = p.next();
  ASSERT_NE(last_valid.flags & protocol::kGazeValid, 0);
  for (std::size_t i = 0; i < closed.size(); ++i) {
    ASSERT_TRUE(closed[i].closed);
    const protocol::GazeSample s = p.next();
    ASSERT_TRUE(all_finite(s));
    EXPECT_EQ(s.flags & protocol::kGazeValid, 0);
    EXPECT_EQ(s.x, last_valid.x);  // held, as the HID source does
    EXPECT_EQ(s.y, last_valid.y);
  }
}

// Closed lids: no pupil data and a blink state (this checks the detector as much as the source: a
// dark spot in the lashes must not pass for a pupil).
TEST(EyePipelineSource, ClosedLidsGiveNoPupilAndABlinkState) {
  Pipeline p(true);
  // As in a real blink: open (the detector tracks the pupil), then closed.
  const auto open = render(*p.eye, p.display, {{5, 3}, {5, 3}, {5, 3}});
  const auto closed = render(*p.eye, p.display, {{5, 3}, {5, 3}, {5, 3}, {5, 3}, {-8, -2}, {12, 6}}, 0.0);
  p.feed(open);
  p.feed(closed);
  for (std::size_t i = 0; i < open.size(); ++i) (void)p.next();
  for (std::size_t i = 0; i < closed.size(); ++i) {
    const protocol::GazeSample s = p.next();
    EXPECT_EQ(s.right.flags & protocol::kEyePupilValid, 0) << "frame " << i;
    EXPECT_EQ(s.state, protocol::EyeMovement::Blink) << "frame " << i;
  }
  EXPECT_EQ(p.source->counts().blinks, closed.size());
}

TEST(EyePipelineSource, WithoutAMapPupilDataFlowsAndGazeStaysInvalid) {
  Pipeline p(false, {}, EyeSide::Left);
  const auto frames = render(*p.eye, p.display, screen_points(p.display, 20));
  p.feed(frames);
  std::size_t pupils = 0;
  for (std::size_t i = 0; i < frames.size(); ++i) {
    const protocol::GazeSample s = p.next();
    ASSERT_TRUE(all_finite(s));
    EXPECT_EQ(s.flags & protocol::kGazeValid, 0);
    EXPECT_EQ(s.right.flags, 0);
    if (s.left.flags & protocol::kEyePupilValid) ++pupils;
    EXPECT_FLOAT_EQ(s.x, 0.5f);  // nothing valid yet: the screen centre
  }
  EXPECT_GE(pupils, frames.size() * 95 / 100);
  EXPECT_NE(p.source->status_detail().find("no calibration"), std::string::npos);
}

TEST(EyePipelineSource, NonFiniteMappedGazeIsAnInvalidSampleNeverNaN) {
  for (const double bad : {std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::infinity(), 1e9}) {
    auto f = std::make_unique<FakeFrames>();
    FakeFrames* frames = f.get();
    EyePipelineOptions po;
    po.detector.leds = LedLayout::preset(2);
    po.map = PupilGlintMap{"broken", [bad](cv::Point2d) { return protocol::Normalized{bad, 0.5}; }};
    EyePipelineSource src(std::move(f), po);
    SyntheticEye eye{SyntheticEyeOptions{}};
    for (auto& r : render(eye, po.display, {{0, 0}, {2, 2}})) frames->frames.push_back(r.frame);
    for (int i = 0; i < 2; ++i) {
      const auto item = src.next();
      ASSERT_TRUE(item);
      const auto& s = std::get<protocol::GazeSample>(*item);
      EXPECT_TRUE(all_finite(s));
      EXPECT_EQ(s.flags & protocol::kGazeValid, 0);
      EXPECT_NE(s.right.flags & protocol::kEyePupilValid, 0);
    }
  }
}

TEST(EyePipelineSource, EmptyAndOddImagesAreInvalidSamplesNotErrors) {
  auto f = std::make_unique<FakeFrames>();
  FakeFrames* frames = f.get();
  EyePipelineSource src(std::move(f), EyePipelineOptions{});
  frames->frames.push_back(EyeFrame{cv::Mat(), 1, 0});
  frames->frames.push_back(EyeFrame{cv::Mat(4, 4, CV_8UC1, cv::Scalar(0)), 2, 1});
  frames->frames.push_back(EyeFrame{cv::Mat(240, 320, CV_8UC1, cv::Scalar(255)), 3, 2});
  for (int i = 0; i < 3; ++i) {
    const auto item = src.next();
    ASSERT_TRUE(item);
    const auto& s = std::get<protocol::GazeSample>(*item);
    EXPECT_TRUE(all_finite(s));
    EXPECT_EQ(s.flags, 0);
    EXPECT_EQ(s.right.flags & protocol::kEyePupilValid, 0);
  }
}

TEST(EyePipelineSource, ReportsFrameSourceProblemsAndEnd) {
  auto f = std::make_unique<FakeFrames>();
  FakeFrames* frames = f.get();
  EyePipelineSource src(std::move(f), EyePipelineOptions{});
  EXPECT_EQ(src.problem(), "");
  EXPECT_EQ(src.description(), "fake-eye-camera 320x240, right eye");
  EXPECT_FALSE(src.next());  // nothing yet: not an end
  EXPECT_FALSE(src.ended());
  frames->st.healthy = false;
  frames->st.problem = "/dev/video0: device lost (unplugged?); retrying every 1 s";
  frames->st.dropped = 7;
  EXPECT_EQ(src.problem(), frames->st.problem);
  EXPECT_NE(src.status_detail().find("7 dropped"), std::string::npos) << src.status_detail();
  frames->st.healthy = true;
  EXPECT_EQ(src.problem(), "");
  frames->end_when_empty = true;
  EXPECT_FALSE(src.next());
  EXPECT_TRUE(src.ended());
}

TEST(EyePipelineSource, RefusesBadDetectorSettings) {
  EyePipelineOptions po;
  po.detector.coarse_downscale = 3;
  EXPECT_THROW(EyePipelineSource(std::make_unique<FakeFrames>(), po), std::invalid_argument);
  EXPECT_EQ(parse_eye_side("left"), EyeSide::Left);
  EXPECT_THROW((void)parse_eye_side("centre"), std::invalid_argument);
}

TEST(SyntheticEyeMotion, BlinksCloseTheLidsWithTransitions) {
  const protocol::DisplayGeometry display;
  SyntheticEyeMotion motion(120, 3, display, 0, 0.05);
  std::vector<SyntheticEyeFrameTruth> t;
  for (int i = 0; i < 120 * 30; ++i) t.push_back(motion.next());  // 30 s
  std::size_t blink = 0, partial = 0;
  for (std::size_t i = 0; i < t.size(); ++i) {
    EXPECT_EQ(t[i].sequence, i);
    EXPECT_EQ(t[i].time_ns, std::llround(static_cast<double>(i) * 1e9 / 120));
    if (t[i].blink) {
      ++blink;
      EXPECT_EQ(t[i].openness, 0);
    } else if (t[i].openness < 1) {
      ++partial;
      EXPECT_GT(t[i].openness, 0);
      // Within 50 ms of a blink frame.
      bool near = false;
      for (std::size_t j = i > 6 ? i - 6 : 0; j < std::min(t.size(), i + 7); ++j) near |= t[j].blink;
      EXPECT_TRUE(near) << i;
    }
    EXPECT_TRUE(std::isfinite(t[i].rotation.yaw_deg) && std::abs(t[i].rotation.yaw_deg) < 40);
  }
  EXPECT_GT(blink, 0u) << "30 s of viewing should hold a blink";
  EXPECT_GT(partial, 0u);
}

TEST(SyntheticEyeFrames, DeliversRenderedFramesWithTheirTruth) {
  SyntheticEyeFramesOptions o;
  o.realtime = false;
  o.start_time_ns = 5'000'000'000;
  SyntheticEyeFrames src(o);
  SyntheticEyeMotion motion(o.rate_hz, o.eye.seed, o.display, 0);
  for (int i = 0; i < 5; ++i) {
    const auto f = src.next(0);
    ASSERT_TRUE(f);
    EXPECT_EQ(f->image.type(), CV_8UC1);
    EXPECT_EQ(f->image.size(), cv::Size(320, 240));
    EXPECT_EQ(f->sequence, static_cast<std::uint64_t>(i));
    const auto m = motion.next();
    EXPECT_EQ(f->time_ns, 5'000'000'000 + m.time_ns);
    EXPECT_EQ(src.last_truth().time_ns, f->time_ns);
    EXPECT_EQ(src.last_truth().rotation.yaw_deg, m.rotation.yaw_deg);
  }
  EXPECT_EQ(src.status().frames, 5u);
  EXPECT_EQ(src.status().description, "synthetic-eye 320x240 120 Hz (seed 1, 2 LEDs)");
  EXPECT_FALSE(src.ended());
  EXPECT_NE(src.pupil_glint_map().description.find("factory calibration"), std::string::npos);
  o.rate_hz = 0;
  EXPECT_THROW(SyntheticEyeFrames{o}, std::invalid_argument);
}

TEST(SyntheticEyeFrames, PacedInRealTimeLikeACamera) {
  SyntheticEyeFramesOptions o;
  o.rate_hz = 50;
  o.eye.width = 160;
  o.eye.height = 120;
  SyntheticEyeFrames src(o);
  const std::int64_t t0 = protocol::monotonic_ns();
  std::vector<std::int64_t> times;
  while (times.size() < 6) {
    if (auto f = src.next(1000)) {
      times.push_back(f->time_ns);
      EXPECT_GE(protocol::monotonic_ns(), f->time_ns);  // never delivered before its time
    }
  }
  const double elapsed = static_cast<double>(protocol::monotonic_ns() - t0) / 1e9;
  EXPECT_GE(elapsed, 0.099);  // 5 periods of 20 ms after the first frame
  EXPECT_EQ(times[5] - times[0], 100'000'000);
  // A short timeout returns nothing while the next frame is not yet due.
  SyntheticEyeFramesOptions slow = o;
  slow.rate_hz = 2;
  SyntheticEyeFrames s2(slow);
  ASSERT_TRUE(s2.next(0));
  EXPECT_FALSE(s2.next(5));
  EXPECT_EQ(s2.status().frames, 1u);
}

TEST(SyntheticEyeFrames, DropsFramesWhenFallingBehind) {
  SyntheticEyeFramesOptions o;
  o.rate_hz = 200;
  o.eye.width = 64;
  o.eye.height = 48;
  o.start_time_ns = protocol::monotonic_ns() - 100'000'000;  // 20 frames late
  SyntheticEyeFrames src(o);
  const auto f = src.next(100);
  ASSERT_TRUE(f);
  EXPECT_GE(f->sequence, 17u);
  EXPECT_GE(src.status().dropped, 17u);
}

TEST(DaemonEyeSources, SyntheticEyeSpecAndEyeOptions) {
  EXPECT_EQ(check_source_spec("synthetic-eye"), "");
  EXPECT_NE(check_source_spec("synthetic-eyes").find("synthetic-eye"), std::string::npos);
  service::EyeConfig e;
  EXPECT_TRUE(check_eye_config(e).empty());
  e.leds = "1,2;oops";
  e.pupil_downscale = 3;
  const auto problems = check_eye_config(e);
  ASSERT_EQ(problems.size(), 2u);
  EXPECT_NE(problems[0].find("eye.leds"), std::string::npos);
  EXPECT_NE(problems[0].find("oops"), std::string::npos);
  EXPECT_NE(problems[1].find("eye.pupil_downscale"), std::string::npos);

  service::DaemonConfig c;
  c.source.spec = "synthetic-eye";
  c.eye.synthetic_width = 160;
  c.eye.synthetic_height = 120;
  c.eye.side = "left";
  auto src = make_source(c, protocol::monotonic_ns());
  EXPECT_EQ(src->nominal_rate_hz(), 120);
  EXPECT_NE(src->description().find("synthetic-eye 160x120 120 Hz"), std::string::npos) << src->description();
  EXPECT_NE(src->description().find("left eye"), std::string::npos) << src->description();
  c.eye.leds = "9";
  EXPECT_THROW((void)make_source(c, 0), std::invalid_argument);
  c.eye.leds = "";
  c.source.rate_hz = 2000;
  EXPECT_THROW((void)make_source(c, 0), std::invalid_argument);
}
