// SPDX-License-Identifier: Apache-2.0
// Eye-movement classification (trackerd/classify/, trackerd/CLASSIFY.md): every method on
// hand-made sequences, accuracy on labelled synthetic gaze degraded like real trackers, the
// online/offline contract (same labels, bounded latency) and garbage input.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <algorithm>
#include <limits>
#include <map>
#include <numbers>
#include <random>
#include <sstream>
#include <string>

#include <sys/wait.h>
#include <unistd.h>

#include "classify/classifier.h"
#include "classify/evaluate.h"
#include "classify/pipeline.h"
#include "classify/trees_core.h"
#include "gaze_scripts.h"
#include "sim/synthetic_labelled.h"
#include "sim/synthetic_gaze.h"

using namespace fovea;
using namespace fovea::trackerd;
using namespace fovea::trackerd::classify;
using fovea::test::Script;
using fovea::test::sample;
using fovea::test::saccade_at;

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

std::vector<std::string> method_names() {
  std::vector<std::string> n;
  for (const auto& c : classifiers()) n.push_back(c.name);
  return n;
}

// --- hand-made sequences ----------------------------------------------------------------------

std::size_t index_at(const std::vector<Sample>& s, double t) {
  for (std::size_t i = 0; i < s.size(); ++i) {
    if (s[i].t_s >= t) return i;
  }
  return s.size() - 1;
}

std::size_t nearest(const std::vector<Sample>& s, double t) {
  std::size_t best = 0;
  for (std::size_t i = 0; i < s.size(); ++i) {
    if (std::abs(s[i].t_s - t) < std::abs(s[best].t_s - t)) best = i;
  }
  return best;
}

double share(const std::vector<Label>& l, std::size_t from, std::size_t to, Label want) {
  double n = 0;
  for (std::size_t i = from; i < to; ++i) n += l[i] == want ? 1 : 0;
  return n / static_cast<double>(to - from);
}

// --- labelled synthetic gaze ---------------------------------------------------------------------

using Labelled = LabelledGaze;

Labelled synthetic(double rate_hz, double seconds, std::uint64_t seed) {
  return synthetic_labelled(rate_hz, seconds, seed);
}

// Pushes one sample at a time, checks order and the latency bound after every push.
std::vector<Label> run_online(const std::string& method, const std::vector<Sample>& samples, double rate) {
  auto c = make_classifier(method, rate);
  const double latency = c->latency_s();
  std::vector<Label> labels;
  std::vector<Labeled> out;
  double newest = -std::numeric_limits<double>::infinity();
  std::size_t pushed = 0;
  for (const Sample& s : samples) {
    c->push(s, out);
    ++pushed;
    if (std::isfinite(s.t_s) && s.t_s > newest) newest = s.t_s;
    for (const Labeled& l : out) {
      EXPECT_EQ(l.index, labels.size()) << method << ": labels out of order";
      labels.push_back(l.label);
    }
    out.clear();
    // Every accepted sample older than the bound has its label.
    for (std::size_t i = labels.size(); i < pushed && samples[i].t_s < newest - latency - 1e-9; ++i) {
      ADD_FAILURE() << method << ": sample " << i << " at t=" << samples[i].t_s << " still unlabelled at t=" << newest
                    << " (latency " << latency << " s)";
      return labels;
    }
  }
  c->flush(out);
  for (const Labeled& l : out) {
    EXPECT_EQ(l.index, labels.size());
    labels.push_back(l.label);
  }
  EXPECT_EQ(labels.size(), samples.size());
  return labels;
}

}  // namespace

// --- registry -----------------------------------------------------------------------------------

TEST(Classify, RegistryAndNames) {
  ASSERT_GE(classifiers().size(), 4u);
  EXPECT_EQ(classifiers().front().name, "gbt");  // the default: GazeCom's pursuit held out (issue 43)
  for (const auto& c : classifiers()) {
    auto m = make_classifier(c.name, 250);
    EXPECT_EQ(m->name(), c.name);
    EXPECT_GE(m->latency_s(), 0);
    EXPECT_LT(m->latency_s(), 0.5);
  }
  try {
    make_classifier("nope", 250);
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("ivt"), std::string::npos) << e.what();  // lists the known ones
  }
  EXPECT_THROW(make_classifier("ivt", 0.0), std::invalid_argument);
  EXPECT_THROW(make_classifier("ivt", kNaN), std::invalid_argument);
  EXPECT_STREQ(to_string(Label::Pso), "pso");
  EXPECT_STREQ(to_string(Label::Lost), "lost");
}

// --- hand-made sequences, every method -------------------------------------------------------------

TEST(Classify, CleanSaccadeBetweenFixations) {
  for (const double rate : {60.0, 250.0, 500.0, 1000.0}) {
    Script sc;
    sc.rate = rate;
    const auto s = sample(sc, 0.8, [](double t) { return saccade_at(t, 0.4, 10); });  // 43 ms, 10 deg
    for (const auto& m : method_names()) {
      const auto l = classify_all(m, rate, s);
      ASSERT_EQ(l.size(), s.size());
      SCOPED_TRACE(m + " at " + std::to_string(rate) + " Hz");
      EXPECT_GT(share(l, index_at(s, 0.1), index_at(s, 0.35), Label::Fixation), 0.95);
      EXPECT_GT(share(l, index_at(s, 0.5), index_at(s, 0.75), Label::Fixation), 0.95);
      // Peak velocity; lee2009's backward difference peaks one sample later at 60 Hz.
      EXPECT_TRUE(l[nearest(s, 0.4215)] == Label::Saccade || (m == "lee2009" && l[nearest(s, 0.4215) + 1] == Label::Saccade));
    }
  }
}

TEST(Classify, SaccadeBoundariesAreTight) {
  // The default method finds onset and offset within a sample or two of the truth (43 ms saccade).
  Script sc;
  sc.rate = 1000;
  const auto s = sample(sc, 0.8, [](double t) { return saccade_at(t, 0.4, 10); });
  const auto l = classify_all("ivvt", 1000, s);
  std::size_t first = 0, last = 0;
  for (std::size_t i = 0; i < l.size(); ++i) {
    if (l[i] == Label::Saccade) {
      if (first == 0) first = i;
      last = i;
    }
  }
  EXPECT_NEAR(static_cast<double>(first), 400, 8);
  EXPECT_NEAR(static_cast<double>(last), 443, 8);
  for (std::size_t i = first; i <= last; ++i) EXPECT_EQ(l[i], Label::Saccade) << i;
}

TEST(Classify, FixationWithShortGapIsFilled) {
  Script sc;
  sc.rate = 250;
  auto s = sample(sc, 0.6, [](double) { return std::pair{2.0, -1.0}; });
  for (std::size_t i = index_at(s, 0.3); i < index_at(s, 0.35); ++i) {  // 50 ms lost: bridged (<= 75 ms)
    s[i].valid = false;
    s[i].x_deg = s[i].y_deg = kNaN;
  }
  for (const std::string m : {"ivvt", "ivt", "idt"}) {
    const auto l = classify_all(m, 250, s);
    EXPECT_EQ(share(l, index_at(s, 0.3), index_at(s, 0.35), Label::Fixation), 1.0) << m;
    EXPECT_GT(share(l, 0, l.size(), Label::Fixation), 0.97) << m;
  }
  // The seed's rule has no fill-in: the gap is lost.
  const auto l = classify_all("lee2009", 250, s);
  EXPECT_EQ(share(l, index_at(s, 0.3), index_at(s, 0.35), Label::Lost), 1.0);
}

// A gap of exactly the fill-in's 75 ms is bridged whatever the clock's origin (pipeline.h
// kTimeSlackS); 1 ms more is not.
TEST(Classify, AGapOfExactlyTheFillInsLimitIsBridgedFromAnyClock) {
  Script sc;
  sc.rate = 1000;
  const auto still = sample(sc, 0.6, [](double) { return std::pair{2.0, -1.0}; });
  const std::size_t last = index_at(still, 0.3);
  for (const double origin : {0.0, 0.1, 1000.003, 86400.77}) {
    for (const std::size_t gap_ms : {75u, 76u}) {
      auto s = still;
      for (Sample& x : s) x.t_s += origin;
      for (std::size_t i = last + 1; i < last + gap_ms; ++i) {
        s[i].valid = false;
        s[i].x_deg = s[i].y_deg = kNaN;
      }
      const auto l = classify_all("ivvt", 1000, s);
      const Label want = gap_ms == 75 ? Label::Fixation : Label::Blink;
      EXPECT_EQ(share(l, last + 1, last + gap_ms, want), 1.0) << gap_ms << " ms from " << origin << " s";
    }
  }
}

TEST(Classify, LongerLossIsBlinkThenLost) {
  Script sc;
  sc.rate = 250;
  auto s = sample(sc, 1.6, [](double) { return std::pair{0.0, 0.0}; });
  const std::size_t a = index_at(s, 0.2), b = index_at(s, 0.4);  // 200 ms: a blink
  const std::size_t c = index_at(s, 0.7), d = index_at(s, 1.5);  // 800 ms: blink for 0.5 s, then lost
  for (std::size_t i = a; i < b; ++i) s[i].valid = false;
  for (std::size_t i = c; i < d; ++i) s[i].x_deg = kNaN;  // NaN position also means lost
  for (const std::string m : {"ivvt", "ivt", "idt"}) {
    const auto l = classify_all(m, 250, s);
    EXPECT_EQ(share(l, a, b, Label::Blink), 1.0) << m;
    EXPECT_EQ(share(l, c, index_at(s, 1.19), Label::Blink), 1.0) << m;
    EXPECT_EQ(share(l, index_at(s, 1.21), d, Label::Lost), 1.0) << m;
  }
}

// The lid uncovering the pupil drags its centre: a blink is followed by a fast movement (SR
// Research's parser embeds every blink in a saccade). It belongs to the blink; a saccade elsewhere
// stays a saccade. (The closing side is left alone: see FrontendOptions::lid_opening_max_s.)
TEST(Classify, TheLidsMovementsAroundABlinkArePartOfIt) {
  Script sc;
  sc.rate = 500;
  // 0.5 s: the lid closes (the gaze sweeps 4 deg down in 30 ms), 150 ms lost, it opens (sweeps back
  // in 30 ms). 1.2 s: a real 8 deg saccade, far from any loss.
  auto s = sample(sc, 2.0, [](double t) {
    const double close = std::clamp((t - 0.5) / 0.03, 0.0, 1.0), open = std::clamp((t - 0.68) / 0.03, 0.0, 1.0);
    const double y = t < 0.68 ? 4.0 * close : 4.0 * (1.0 - open);
    return std::pair{saccade_at(t, 1.2, 8.0).first, y};
  });
  const std::size_t lost_from = index_at(s, 0.53), lost_to = index_at(s, 0.68);
  for (std::size_t i = lost_from; i < lost_to; ++i) s[i].valid = false;
  for (const std::string m : {"ivvt", "ivt"}) {
    const auto l = run_online(m, s, 500);
    EXPECT_EQ(share(l, lost_from, lost_to, Label::Blink), 1.0) << m;
    EXPECT_EQ(share(l, lost_to, index_at(s, 0.705), Label::Saccade), 0.0) << m << ": the lid opening is a saccade";
    EXPECT_GT(share(l, lost_to, index_at(s, 0.705), Label::Blink), 0.8) << m;
    EXPECT_GT(share(l, index_at(s, 1.205), index_at(s, 1.23), Label::Saccade), 0.8) << m << ": the real saccade";
    EXPECT_EQ(share(l, index_at(s, 1.0), index_at(s, 1.5), Label::Blink), 0.0) << m;
  }
  // lee2009 keeps its published rule, idt its own (its "saccade" is anything but a fixation).
  for (const std::string m : {"idt", "lee2009"}) {
    const auto l = run_online(m, s, 500);
    EXPECT_EQ(share(l, lost_to, index_at(s, 0.705), Label::Blink), 0.0) << m;
  }
}

TEST(Classify, BlinkEdgesTakeOnlyWhatFollowsABlinkForTheLidsUpPhase) {
  // Labels at 1 kHz: S = saccade, P = PSO, F = fixation, B = blink.
  const auto run = [](const std::string& script) {
    BlinkEdges edges(0.200);
    std::vector<Labeled> out;
    std::uint64_t i = 0;
    for (const char c : script) {
      const Label l = c == 'S' ? Label::Saccade : c == 'P' ? Label::Pso : c == 'B' ? Label::Blink : Label::Fixation;
      edges.push({i, l}, static_cast<double>(i) * 1e-3, out);
      ++i;
    }
    std::string back;
    for (const Labeled& l : out) back += l.label == Label::Saccade ? 'S' : l.label == Label::Pso ? 'P' : l.label == Label::Blink ? 'B' : 'F';
    return back;
  };
  EXPECT_EQ(run("FFSSPPBBSSPFF"), "FFSSPPBBBBBFF") << "opening taken; closing left (no labels held back)";
  EXPECT_EQ(run("FFBBFFSSFF"), "FFBBFFSSFF") << "a saccade after a fixation is no lid's";
  const std::string long_run(300, 'S');
  EXPECT_EQ(run("BB" + long_run + "F"), "BB" + std::string(201, 'B') + std::string(99, 'S') + "F")
      << "the lid opens for at most 200 ms";
  EXPECT_EQ(run("BBSSFFSSBBPP"), "BBBBFFSSBBBB");
}

TEST(Classify, NanRunsAreLost) {
  // Data lost from the start (no eye seen yet) is lost, not a blink; so is everything for lee2009.
  Script sc;
  sc.rate = 250;
  auto s = sample(sc, 0.5, [](double) { return std::pair{0.0, 0.0}; });
  for (std::size_t i = 0; i < 50; ++i) s[i].x_deg = s[i].y_deg = kNaN;
  for (const auto& m : method_names()) {
    const auto l = classify_all(m, 250, s);
    EXPECT_EQ(share(l, 0, 50, Label::Lost), 1.0) << m;
  }
  std::vector<Sample> all_nan(100);
  for (std::size_t i = 0; i < all_nan.size(); ++i) all_nan[i] = {static_cast<double>(i) / 100, kNaN, kNaN, false, 0};
  for (const auto& m : method_names()) {
    for (const Label l : classify_all(m, 100, all_nan)) EXPECT_EQ(l, Label::Lost) << m;
  }
}

TEST(Classify, BlinkFromPupilAspect) {
  // Lee 2009 §3.5.2: aspect ratio < 0.7 is a blink even while the tracker still reports gaze.
  Script sc;
  sc.rate = 60;
  auto s = sample(sc, 1.0, [](double) { return std::pair{0.0, 0.0}; });
  for (auto& x : s) x.pupil_aspect = 0.95;
  for (std::size_t i = 20; i < 30; ++i) s[i].pupil_aspect = 0.5;
  s[40].pupil_aspect = 0.69;
  s[50].pupil_aspect = 0.71;  // apart from the blink before: gbt learned that coders call its neighbours noise
  for (const auto& m : method_names()) {
    const auto l = classify_all(m, 60, s);
    EXPECT_EQ(share(l, 20, 30, Label::Blink), 1.0) << m;
    EXPECT_EQ(l[40], Label::Blink) << m;
    EXPECT_NE(l[50], Label::Blink) << m;
    EXPECT_NE(l[10], Label::Blink) << m;
  }
}

TEST(Classify, PursuitRamp) {
  // 10 deg/s for 1 s between fixations: pursuit for the default method; I-VT (30 deg/s) calls it fixation.
  for (const double rate : {60.0, 250.0, 1000.0}) {
    Script sc;
    sc.rate = rate;
    sc.noise = 0.03;
    const auto s = sample(sc, 1.6, [](double t) { return std::pair{10 * std::clamp(t - 0.3, 0.0, 1.0), 0.0}; });
    const auto l = classify_all("ivvt", rate, s);
    SCOPED_TRACE(rate);
    EXPECT_GT(share(l, index_at(s, 0.45), index_at(s, 1.15), Label::Pursuit), 0.95);
    EXPECT_GT(share(l, index_at(s, 0.0), index_at(s, 0.2), Label::Fixation), 0.95);
    EXPECT_GT(share(l, index_at(s, 1.4), l.size(), Label::Fixation), 0.95);
    const auto v = classify_all("ivt", rate, s);
    EXPECT_GT(share(v, index_at(s, 0.45), index_at(s, 1.15), Label::Fixation), 0.95);
  }
}

// tangent_vector: per-axis angle changes as the eye's rotation, exact for small changes anywhere.
TEST(Classify, TangentVectorIsTheTrueAngularChange) {
  const TangentVector c = tangent_vector(0, 0, 3, -4);
  EXPECT_NEAR(c.x, 3, 1e-12);
  EXPECT_NEAR(c.y, -4, 1e-12);
  // At 40 deg horizontal eccentricity a per-axis vertical change is cos 40 deg of an angle, a
  // horizontal one exactly one.
  const TangentVector v = tangent_vector(40, 0, 0, 1);
  EXPECT_NEAR(v.x, 0, 1e-12);
  EXPECT_NEAR(v.y, std::cos(40 * std::numbers::pi / 180), 1e-12);
  EXPECT_NEAR(tangent_vector(40, 0, 1, 0).x, 1, 1e-12);
  // Anywhere, the length of a small change is the angle between the two directions, and its first
  // axis follows increasing x (same sign as dx where dy = 0).
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> pos(-60, 60), dir(0, 2 * std::numbers::pi);
  for (int i = 0; i < 200; ++i) {
    const double x = pos(rng), y = pos(rng), a = dir(rng), h = 1e-4;
    const double dx = h * std::cos(a), dy = h * std::sin(a);
    const TangentVector w = tangent_vector(x, y, dx, dy);
    EXPECT_NEAR(std::hypot(w.x, w.y), angle_between_deg(x, y, x + dx, y + dy), 1e-4 * h) << x << "," << y;
    EXPECT_GT(tangent_vector(x, y, h, 0).x, 0);
    EXPECT_GT(tangent_vector(x, y, 0, h).y, 0);
  }
}

// A movement's label does not depend on where on the screen it happens: per-axis angles overstated
// a vertical pursuit at 25 deg/s, 50 deg to the side (a wide screen or a headset), as 39 deg/s,
// over the 30 deg/s saccade floor.
TEST(Classify, AMovementsLabelDoesNotDependOnItsEccentricity) {
  const double deg = std::numbers::pi / 180;
  for (const double rate : {250.0, 1000.0}) {
    Script sc;
    sc.rate = rate;
    sc.noise = 0.01;
    // Along the great circle through (azimuth, 0) and straight up, at 25 deg/s for 0.6 s.
    const auto vertical_pursuit = [&](double azimuth) {
      return sample(sc, 1.4, [azimuth, deg](double t) {
        const double phi = 25 * std::clamp(t - 0.3, 0.0, 0.6) * deg;
        return std::pair{azimuth, std::atan(std::tan(phi) / std::cos(azimuth * deg)) / deg};
      });
    };
    const auto centre = vertical_pursuit(0), side = vertical_pursuit(50);
    const auto lc = classify_all("ivvt", rate, centre), ls = classify_all("ivvt", rate, side);
    SCOPED_TRACE(rate);
    EXPECT_EQ(share(ls, 0, ls.size(), Label::Saccade), 0.0) << "25 deg/s is no saccade, anywhere";
    EXPECT_GT(share(ls, index_at(side, 0.45), index_at(side, 0.85), Label::Pursuit), 0.95);
    std::size_t differ = 0;
    for (std::size_t i = 0; i < lc.size(); ++i) differ += lc[i] != ls[i] ? 1u : 0u;
    EXPECT_LE(differ, 2u) << "the same movement, 50 deg to the side";
  }
}

// The eye drifting on by `deg` after a saccade that ended at `end`, settling within ~0.1 s: what
// pupil-based trackers show after a saccade (Nystrom, Hooge & Holmqvist 2013).
namespace {
double settling(double t, double end, double deg) { return t > end ? deg * (1.0 - std::exp(-(t - end) / 0.03)) : 0.0; }
}  // namespace

// Issue 25: on human-coded EyeLink data, ivvt called the eye settling after a saccade pursuit.
TEST(Classify, SettlingAfterASaccadeIsNoPursuitButCatchUpPursuitGoesOn) {
  Script sc;
  sc.rate = 500;
  sc.noise = 0.01;
  // Fixation, an 8 deg saccade at 0.5 s, then the eye drifts 0.4 deg further over ~60 ms, settles.
  const auto settle = sample(sc, 1.2, [](double t) {
    return std::pair{saccade_at(t, 0.5, 8.0).first + settling(t, 0.5 + saccade_duration_s(8.0), 0.4), 0.0};
  });
  const auto l = run_online("ivvt", settle, 500);
  EXPECT_EQ(share(l, index_at(settle, 0.56), index_at(settle, 0.75), Label::Pursuit), 0.0)
      << "the settling after a saccade from a fixation is no pursuit";
  // Pursuit at 10 deg/s, a 1 deg catch-up saccade at 0.6 s, pursuit goes on.
  const auto chase = sample(sc, 1.4, [](double t) {
    return std::pair{10.0 * t + saccade_at(t, 0.6, 1.0).first, 0.0};
  });
  const auto c = run_online("ivvt", chase, 500);
  EXPECT_GT(share(c, index_at(chase, 0.65), index_at(chase, 0.75), Label::Pursuit), 0.9)
      << "after a catch-up saccade the eye is still pursuing";
}

// Issue 25: on still images ivvt called a quarter of all samples pursuit. Drift and a video
// tracker's slow wander move the eye at pursuit-like speeds for a while but stay within a
// fixation's range (Larsson et al. 2015: 1.9 deg); pursuit leaves it.
TEST(Classify, DriftWithinAFixationsRangeIsNoPursuit) {
  for (const double rate : {250.0, 500.0, 1000.0}) {
    Script sc;
    sc.rate = rate;
    sc.noise = 0.01;
    // 0.5 s still, then 4 deg/s for 200 ms (0.8 deg) one way, still, 3 deg/s back for 150 ms.
    const auto drift = sample(sc, 1.6, [](double t) {
      const double out = 4.0 * std::clamp(t - 0.5, 0.0, 0.2);
      const double back = 3.0 * std::clamp(t - 1.0, 0.0, 0.15);
      return std::pair{out - back, 0.25 * out};
    });
    SCOPED_TRACE(rate);
    const auto l = run_online("ivvt", drift, rate);
    EXPECT_EQ(share(l, 0, drift.size(), Label::Pursuit), 0.0) << "drift within 1 deg is fixation";
    EXPECT_GT(share(l, 0, drift.size(), Label::Fixation), 0.99);
    // The same speed kept up long enough to leave 1.9 deg behind is pursuit from where a sample
    // sees that happen within its 200 ms of look-ahead: 1.9 / 4 - 0.2 = 0.275 s into the run.
    const auto chase = sample(sc, 1.6, [](double t) { return std::pair{4.0 * std::clamp(t - 0.3, 0.0, 1.0), 0.0}; });
    const auto c = run_online("ivvt", chase, rate);
    EXPECT_GT(share(c, index_at(chase, 0.62), index_at(chase, 1.2), Label::Pursuit), 0.95);
    EXPECT_GT(share(c, index_at(chase, 0.35), index_at(chase, 0.5), Label::Fixation), 0.95);
  }
}

TEST(Classify, AfterACatchUpSaccadePursuitGoesOnOnlyInItsDirection) {
  Script sc;
  sc.rate = 500;
  sc.noise = 0.01;
  // Pursuit to the right at 10 deg/s, a 6 deg saccade back left at 0.8 s onto a still target,
  // and the eye settles 0.4 deg downwards (a direction the pursuit never had).
  const auto s = sample(sc, 1.4, [](double t) {
    return std::pair{10.0 * std::min(t, 0.8) - saccade_at(t, 0.8, 6.0).first, settling(t, 0.8 + saccade_duration_s(6.0), -0.4)};
  });
  const auto l = run_online("ivvt", s, 500);
  EXPECT_GT(share(l, index_at(s, 0.3), index_at(s, 0.75), Label::Pursuit), 0.95);
  EXPECT_EQ(share(l, index_at(s, 0.86), l.size(), Label::Pursuit), 0.0)
      << "settling at right angles to the pursuit after a saccade is no catch-up";
}

namespace {
// 0.8 s at 1000 Hz (0.005 deg noise) with a saccade of `amplitude` deg along x at 0.4 s, whose
// landing then moves by `after(time since its offset)` deg; returns the samples and the offset.
std::pair<std::vector<Sample>, double> saccade_then(double amplitude, double (*after)(double)) {
  Script sc;
  sc.rate = 1000;
  sc.noise = 0.005;
  const double off = 0.4 + (2.2 * amplitude + 21) / 1000;
  auto s = sample(sc, 0.8, [&](double t) {
    auto p = saccade_at(t, 0.4, amplitude);
    if (t > off) p.first += after(t - off);
    return p;
  });
  return {std::move(s), off};
}
// A 10 deg saccade whose landing wobbles: a damped 0.5 deg, 25 Hz oscillation (a PSO).
std::pair<std::vector<Sample>, double> wobbling_saccade() {
  return saccade_then(10, [](double dt) {
    return 0.5 * std::exp(-dt / 0.015) * std::sin(2 * std::numbers::pi * 25 * dt);
  });
}
}  // namespace

TEST(Classify, PostSaccadicOscillation) {
  // The wobble after landing (a PSO) is labelled pso, not saccade or fixation.
  const auto [s, off] = wobbling_saccade();
  const auto l = classify_all("ivvt", 1000, s);
  // The first, outward half-cycle continues the saccade's motion (the overshoot stays in the
  // saccade); the return swing is the PSO.
  EXPECT_GT(share(l, index_at(s, off + 0.008), index_at(s, off + 0.02), Label::Pso), 0.9);
  EXPECT_EQ(l[index_at(s, off - 0.01)], Label::Saccade);
  EXPECT_GT(share(l, index_at(s, off + 0.06), index_at(s, 0.75), Label::Fixation), 0.95);
  // Without the wobble: no PSO at all.
  const auto clean = saccade_then(10, [](double) { return 0.0; }).first;
  EXPECT_EQ(share(classify_all("ivvt", 1000, clean), 0, clean.size(), Label::Pso), 0.0);
}

// gbt's three PSO conventions (classifier.h, PsoConvention) on one saccade with a PSO: onset (the
// EyeLink and Lund coders'): ivvt's PSO wherever it finds one; none (GazeCom's coders'): no PSO
// class, the trees' labels alone; separate (the default): the trees' saccade as it is (GazeCom's
// end), ivvt's PSO after it where the trees say fixation.
TEST(Classify, GbtsPsoFromTheOnsetAfterTheTreesSaccadeOrNotAtAll) {
  const auto [s, off] = wobbling_saccade();
  ClassifierOptions o;
  o.nominal_rate_hz = 1000;
  const auto separate = classify_all("gbt", o, s);
  o.pso = PsoConvention::Onset;
  const auto onset = classify_all("gbt", o, s);
  o.trees_only = true;
  const auto trees = classify_all("gbt", o, s);
  o.trees_only = false;
  o.pso = PsoConvention::None;
  const auto none = classify_all("gbt", o, s);
  const auto ivvt = classify_all("ivvt", 1000, s);
  EXPECT_EQ(share(trees, 0, s.size(), Label::Pso), 0.0);  // GazeCom's coders have no PSO class
  EXPECT_EQ(share(none, 0, s.size(), Label::Pso), 0.0);
  EXPECT_GT(share(onset, index_at(s, off + 0.008), index_at(s, off + 0.02), Label::Pso), 0.9);
  std::size_t after_saccade = 0, cut_short = 0;
  for (std::size_t i = 0; i < s.size(); ++i) {
    // onset: ivvt's PSO wherever the trees say saccade or fixation; otherwise the trees' labels
    if (ivvt[i] == Label::Pso) {
      ASSERT_TRUE(onset[i] != Label::Saccade && onset[i] != Label::Fixation) << i;
    }
    if (onset[i] != Label::Pso) {
      ASSERT_EQ(none[i], onset[i]) << i;
    } else {
      ASSERT_EQ(ivvt[i], Label::Pso) << i;
      ASSERT_TRUE(none[i] == Label::Saccade || none[i] == Label::Fixation) << i;
    }
    // separate: the trees' saccade kept whole, ivvt's PSO where they say fixation
    if (none[i] == Label::Saccade) {
      ASSERT_EQ(separate[i], Label::Saccade) << i;
      cut_short += onset[i] == Label::Pso;
    } else if (separate[i] != none[i]) {
      ASSERT_EQ(separate[i], Label::Pso) << i;
      ASSERT_EQ(none[i], Label::Fixation) << i;
      ASSERT_EQ(ivvt[i], Label::Pso) << i;
      ++after_saccade;
    }
  }
  EXPECT_GT(after_saccade, 5u) << "the PSO after the trees' saccade";
  EXPECT_GT(cut_short, 0u) << "where the trees' saccade runs into ivvt's PSO the conventions differ";
  // ivvt's PSO marks are final within 50 ms, so taking them costs no latency beyond the trees' own
  // (they waited for ivvt's whole label, 310 ms, before).
  ClassifierOptions with_marks = o;
  with_marks.pso = PsoConvention::Separate;
  EXPECT_EQ(make_classifier("gbt", o)->latency_s(), make_classifier("gbt", with_marks)->latency_s());
  with_marks.pso = PsoConvention::Onset;
  EXPECT_EQ(make_classifier("gbt", o)->latency_s(), make_classifier("gbt", with_marks)->latency_s());
  for (const PsoConvention c : {PsoConvention::None, PsoConvention::Onset}) {
    o.pso = c;
    try {
      (void)make_classifier("ivvt", o);
      ADD_FAILURE() << "ivvt with pso " << to_string(c);
    } catch (const std::invalid_argument& e) {
      EXPECT_EQ(std::string(e.what()), std::string("classifier ivvt: only gbt takes a PSO convention (pso ") +
                                           to_string(c) + "; ivvt's PSO is part of its rule)");
    }
  }
  EXPECT_EQ(pso_convention("onset"), PsoConvention::Onset);
  EXPECT_EQ(pso_convention("Separate"), std::nullopt);
}

// The smoothing's choice weighs pursuit by the model's chain weight (trees_core.h, GbtModel::weights)
// or by the user's: more weight, more pursuit (taken from fixation), never a moved saccade.
TEST(Classify, GbtsPursuitWeightTradesFixationForPursuitAndTheModelStatesItsOwn) {
  const Labelled d = synthetic(250, 30, 5);
  ClassifierOptions o;
  o.nominal_rate_hz = 250;
  const auto count = [&](double weight, Label l) {
    o.pursuit_weight = weight;
    const auto labels = classify_all("gbt", o, d.samples);
    return std::count(labels.begin(), labels.end(), l);
  };
  const auto model = builtin_gbt_model();
  const std::size_t pursuit = model->context(false)->class_of(Label::Pursuit);
  ASSERT_LT(pursuit, model->weights(false).size());
  EXPECT_EQ(count(0, Label::Pursuit), count(model->weights(false)[pursuit], Label::Pursuit));
  const auto low = count(0.3, Label::Pursuit), high = count(4, Label::Pursuit);
  EXPECT_GT(low, 0);
  EXPECT_GT(high, low + 50);
  EXPECT_EQ(count(0.3, Label::Saccade), count(4, Label::Saccade));
  for (const double bad : {-1.0, std::numeric_limits<double>::quiet_NaN()}) {
    o.pursuit_weight = bad;
    EXPECT_THROW((void)make_classifier("gbt", o), std::invalid_argument);
  }
  o.pursuit_weight = 2;
  try {
    (void)make_classifier("ivvt", o);
    ADD_FAILURE() << "ivvt with a pursuit weight";
  } catch (const std::invalid_argument& e) {
    EXPECT_STREQ(e.what(), "classifier ivvt: only gbt weighs its classes (ivvt's pursuit is a rule's)");
  }
}

// The model's online chain holds doubtful fixations (trees_core.h, OnsetHold): against no hold, the
// only labels that change are fixations turned pursuit, each run of them ending where a pursuit
// begins; saccades never move; and a held label is final within the chain's bound.
TEST(Classify, GbtsHoldTurnsOnlyFixationsBeforeAPursuitIntoItsStart) {
  const Labelled d = synthetic(250, 30, 5);
  ClassifierOptions o;
  o.nominal_rate_hz = 250;
  ASSERT_GT(builtin_gbt_model()->hold(false).hold_s, 0) << "the built-in model's online chain holds";
  const OnlineLabels held = classify_online("gbt", o, d.samples);
  o.pursuit_hold = PursuitHold{};  // none
  const OnlineLabels plain = classify_online("gbt", o, d.samples);
  ASSERT_EQ(held.labels.size(), plain.labels.size());
  std::size_t changed = 0;
  for (std::size_t i = 0; i < held.labels.size(); ++i) {
    if (held.labels[i] == plain.labels[i]) continue;
    ++changed;
    ASSERT_EQ(plain.labels[i], Label::Fixation) << i;
    ASSERT_EQ(held.labels[i], Label::Pursuit) << i;
    std::size_t j = i;  // the run of turned fixations leads into a pursuit of the plain labels
    while (j < held.labels.size() && held.labels[j] != plain.labels[j]) ++j;
    ASSERT_LT(j, held.labels.size());
    EXPECT_EQ(plain.labels[j], Label::Pursuit) << "the run from " << i << " ends in " << to_string(plain.labels[j]);
    const double wait = held.final_t_s[i] - d.samples[i].t_s;
    EXPECT_LE(wait, make_classifier("gbt", ClassifierOptions{})->latency_s() + 1e-9) << i;
  }
  EXPECT_GT(changed, 0u) << "no onset moved: the test shows nothing";
}

// Where a tracker's clock starts must not move a label: its timestamps are doubles in seconds, so
// a neighbour exactly 8 ms (or 10, 32, 40 ms) away comes out a hair over or under it depending on
// the clock's origin, and windows that took such a sample or not at random moved a saccade's edges
// by a sample (pipeline.h kTimeSlackS, context.h kContextSlackS).
TEST(Classify, LabelsDoNotDependOnWhereTheClockStarts) {
  for (const double rate : {250.0, 1000.0}) {
    const Labelled d = synthetic(rate, 10, 11);
    for (const std::string& method : method_names()) {
      for (const bool offline : {false, true}) {
        if (offline && method != "gbt") continue;
        ClassifierOptions o;
        o.nominal_rate_hz = rate;
        o.offline = offline;
        const auto reference = classify_all(method, o, d.samples);
        for (const double origin : {0.1, 1000.003, 86400.77}) {
          std::vector<Sample> shifted = d.samples;
          for (Sample& s : shifted) s.t_s += origin;
          const auto labels = classify_all(method, o, shifted);
          ASSERT_EQ(labels.size(), reference.size());
          std::size_t moved = 0;
          for (std::size_t i = 0; i < labels.size(); ++i) moved += labels[i] != reference[i];
          EXPECT_EQ(moved, 0u) << method << (offline ? " offline" : "") << " at " << rate << " Hz, the clock from "
                               << origin << " s";
        }
      }
    }
  }
}

// What gbt takes from ivvt (trees_core.cpp, WithIvvtMarksCore): ivvt's marks alone, sent as soon as a
// sample's mark is final. They must be the full labels' saccade and PSO samples exactly, each within
// the marks' bound (the front end's, plus 10 ms of velocity window, the 40 ms PSO window and 30 ms
// for a saccade's onset to walk back), where the full label waits up to ivvt's 385 ms.
TEST(Classify, IvvtsMarksAreTheFullLabelsSaccadesAndPsoAndComeWithin80ms) {
  for (const double rate : {250.0, 500.0, 1000.0}) {
    const Labelled d = synthetic_labelled(rate, 20, 3, /*realistic=*/true);
    const std::vector<Label> full = classify_all("ivvt", rate, d.samples);
    Pipeline marks("ivvt-marks", FrontendOptions{}, make_ivvt_marks_core());  // ivvt's own front end
    const double bound = marks.latency_s();
    EXPECT_LT(bound, 0.2);
    std::vector<Label> got(d.samples.size(), Label::Lost);
    std::vector<Labeled> out;
    double worst = 0;
    for (const Sample& s : d.samples) {
      marks.push(s, out);
      for (const Labeled& l : out) {
        got[l.index] = l.label;
        worst = std::max(worst, s.t_s - d.samples[l.index].t_s);
      }
      out.clear();
    }
    marks.flush(out);
    for (const Labeled& l : out) got[l.index] = l.label;
    std::size_t pso = 0, saccade = 0;
    for (std::size_t i = 0; i < full.size(); ++i) {
      ASSERT_EQ(got[i] == Label::Pso, full[i] == Label::Pso) << rate << " Hz, sample " << i;
      ASSERT_EQ(got[i] == Label::Saccade, full[i] == Label::Saccade) << rate << " Hz, sample " << i;
      pso += full[i] == Label::Pso;
      saccade += full[i] == Label::Saccade;
    }
    EXPECT_GT(pso, 50u) << rate << " Hz: the test shows nothing";
    EXPECT_GT(saccade, 100u) << rate << " Hz: the test shows nothing";
    EXPECT_LE(worst, bound + 1e-9) << rate << " Hz";
  }
}

namespace {
// gbt's trees without ivvt's marks beside them (`--pso none`), on a 1000 Hz stream.
std::vector<Label> gbt_trees_alone(const std::vector<Sample>& s) {
  ClassifierOptions o;
  o.nominal_rate_hz = 1000;
  o.pso = PsoConvention::None;
  return classify_all("gbt", o, s);
}
}  // namespace

// GazeCom's expert, whom gbt's trees learned from, leaves most saccades under 1 degree unmarked;
// the EyeLink and Lund coders mark them. With its PSO class (the default) gbt takes a saccade of
// ivvt's that lies wholly in the trees' fixation (trees_core.cpp, WithIvvtMarksCore); the trees
// alone (`--pso none`) leave it in the fixation. Its labels stay within the bound.
TEST(Classify, GbtTakesIvvtsSmallSaccadesWhereItsTreesSeeOnlyFixation) {
  for (const double amplitude : {0.5, 0.6}) {
    SCOPED_TRACE(amplitude);
    const auto [s, off] = saccade_then(amplitude, [](double) { return 0.0; });
    const std::size_t from = index_at(s, 0.4), to = index_at(s, off);
    const auto ivvt = classify_all("ivvt", 1000, s);
    ASSERT_GT(share(ivvt, from, to, Label::Saccade), 0.5) << "ivvt misses the saccade: the test shows nothing";
    const auto with = run_online("gbt", s, 1000);  // the default: the trees with ivvt's marks
    const auto alone = gbt_trees_alone(s);
    ASSERT_EQ(share(alone, from - 20, to + 20, Label::Saccade), 0.0) << "the trees see this saccade themselves";
    std::size_t added = 0;
    for (std::size_t i = 0; i < s.size(); ++i) {
      if (with[i] == alone[i]) continue;
      ASSERT_EQ(with[i], Label::Saccade) << i;
      ASSERT_EQ(ivvt[i], Label::Saccade) << i;
      ASSERT_EQ(alone[i], Label::Fixation) << i;
      ++added;
    }
    const auto ivvts = static_cast<std::size_t>(std::count(ivvt.begin(), ivvt.end(), Label::Saccade));
    EXPECT_EQ(added, ivvts) << "ivvt's whole saccade, nothing else";
  }
}

// ...but not one the noise before it could make: where in the 100 ms before it the gaze moves (by
// ivvt's smoothed speed) half as far in the saccade's duration as the saccade does, the trees'
// fixation stays. A 25 Hz wobble of 0.2 deg there is such noise. Jitter from sample to sample that
// the smoothed speed averages away is not: the saccade stays taken behind a +-0.1 deg zigzag.
TEST(Classify, GbtLeavesIvvtsSmallSaccadeThatTheNoiseBeforeItCouldMake) {
  for (const bool wobble : {true, false}) {
    SCOPED_TRACE(wobble ? "a 25 Hz wobble before" : "a zigzag before");
    auto [s, off] = saccade_then(0.5, [](double) { return 0.0; });
    for (std::size_t i = index_at(s, 0.3); i < index_at(s, 0.4); ++i) {
      s[i].y_deg += wobble ? 0.2 * std::sin(2 * std::numbers::pi * 25 * (s[i].t_s - 0.3)) : (i % 2 ? 0.1 : -0.1);
    }
    const std::size_t from = index_at(s, 0.4), to = index_at(s, off);
    const auto ivvt = classify_all("ivvt", 1000, s);
    ASSERT_GT(share(ivvt, from, to, Label::Saccade), 0.5) << "ivvt misses the saccade: the test shows nothing";
    const auto alone = gbt_trees_alone(s);
    ASSERT_EQ(share(alone, from - 20, to + 20, Label::Saccade), 0.0) << "the trees see this saccade themselves";
    const auto with = run_online("gbt", s, 1000);
    const double taken = share(with, from - 20, to + 20, Label::Saccade);
    if (wobble) {
      EXPECT_EQ(taken, 0.0) << "a saccade under twice the noise's reach taken";
    } else {
      EXPECT_GT(taken, 0.0) << "a saccade left out for noise the smoothed speed does not see";
    }
  }
}

TEST(Classify, ThePsosSlowSwingBackIsPsoToo) {
  // A pupil-based tracker's PSO overshoots and returns (Hooge et al. 2015): here the eye lands
  // 0.4 deg beyond the target and comes back within ~50 ms, slower than the landing itself, so the
  // speed never rises again; the swing back against the saccade's direction is the PSO.
  const auto [s, off] = saccade_then(10.4, [](double dt) { return -0.4 * (1 - std::exp(-dt / 0.012)); });
  const auto l = classify_all("ivvt", 1000, s);
  EXPECT_GT(share(l, index_at(s, off + 0.01), index_at(s, off + 0.025), Label::Pso), 0.9);
  EXPECT_GT(share(l, index_at(s, off + 0.08), index_at(s, 0.75), Label::Fixation), 0.95);
}

TEST(Classify, RateChangesMidStream) {
  // 250 Hz, then 1000 Hz, then 60 Hz, each with a saccade: methods work on times, not counts.
  std::vector<Sample> s;
  std::mt19937_64 rng(5);
  std::normal_distribution<double> g(0, 0.01);
  double t = 0;
  const auto segment = [&](double rate, double seconds, double base) {
    const double t_end = t + seconds, t_sacc = t + seconds / 2;
    for (; t < t_end; t += 1 / rate) {
      Sample x;
      x.t_s = t;
      x.x_deg = base + saccade_at(t, t_sacc, 8).first + g(rng);
      x.y_deg = g(rng);
      s.push_back(x);
    }
  };
  // On the display throughout (-8 to 16 deg; it reaches +-22 deg): gbt learned GazeCom's coders'
  // noise for gaze off the screen.
  segment(250, 0.8, -8);
  segment(1000, 0.8, 0);
  segment(60, 0.8, 8);
  for (const auto& m : method_names()) {
    const auto l = classify_all(m, 250, s);
    SCOPED_TRACE(m);
    for (const double ts : {0.4, 1.2, 2.0}) {
      const std::size_t peak = nearest(s, ts + 0.019);
      EXPECT_TRUE(l[peak] == Label::Saccade || (m == "lee2009" && l[peak + 1] == Label::Saccade)) << ts;
      EXPECT_GT(share(l, index_at(s, ts - 0.3), index_at(s, ts - 0.05), Label::Fixation), 0.9) << ts;
    }
  }
}

TEST(Classify, IvtMergesAndDiscardsLikeTobii) {
  Script sc;
  sc.rate = 500;
  sc.noise = 0.0;
  // Two outlying samples (a glint artefact) inside a fixation: the velocity windows that reach them
  // exceed 30 deg/s, splitting the fixation; merging (< 75 ms, < 0.5 deg) makes it one again.
  auto s = sample(sc, 0.6, [](double) { return std::pair{0.0, 0.0}; });
  s[150].x_deg = s[151].x_deg = 2.0;
  auto l = classify_all("ivt", 500, s);
  for (std::size_t i = 0; i < l.size(); ++i) {
    EXPECT_EQ(l[i], Label::Fixation) << i;
  }
  // A 40 ms fixation between two saccades is discarded (< 60 ms): unknown.
  s = sample(sc, 0.8, [](double t) {
    return std::pair{saccade_at(t, 0.3, 5).first + saccade_at(t, 0.3 + 0.032 + 0.040, 5).first, 0.0};
  });
  l = classify_all("ivt", 500, s);
  const std::size_t mid = index_at(s, 0.3 + 0.032 + 0.02);
  EXPECT_EQ(l[mid], Label::Unknown);
  EXPECT_EQ(l[index_at(s, 0.15)], Label::Fixation);
}

TEST(Classify, IdtDispersionWindow) {
  Script sc;
  sc.rate = 250;
  sc.noise = 0.05;
  const auto s = sample(sc, 0.8, [](double t) { return saccade_at(t, 0.4, 10); });
  const auto l = classify_all("idt", 250, s);
  EXPECT_GT(share(l, index_at(s, 0.05), index_at(s, 0.38), Label::Fixation), 0.99);
  EXPECT_GT(share(l, index_at(s, 0.41), index_at(s, 0.43), Label::Saccade), 0.99);
}

TEST(Classify, Lee2009Thresholds) {
  // Normalized speed per 60 Hz frame on the default display (531 mm wide at 650 mm): 0.03 of the
  // width per frame is about 1.4 deg per frame (84 deg/s); 0.1 is about 4.7 deg per frame.
  const auto run = [](double deg_per_s, double rate) {
    std::vector<Sample> s;
    for (int i = 0; i < 10; ++i) s.push_back({i / rate, deg_per_s * i / rate - 2, 0, true, 0});
    return classify_all("lee2009", rate, s);
  };
  EXPECT_EQ(run(50, 60)[3], Label::Fixation);
  EXPECT_EQ(run(150, 60)[3], Label::Pursuit);  // Lee's "drift"
  EXPECT_EQ(run(400, 60)[1], Label::Saccade);
  EXPECT_EQ(run(50, 60)[0], Label::Unknown);  // no previous sample
  // Rate-independent: the same speeds at 240 Hz give the same labels.
  EXPECT_EQ(run(50, 240)[5], Label::Fixation);
  EXPECT_EQ(run(150, 240)[5], Label::Pursuit);
  EXPECT_EQ(run(400, 240)[5], Label::Saccade);
}

// --- online == offline, latency, garbage -----------------------------------------------------------

TEST(Classify, OnlineEqualsOfflineAndLatencyHolds) {
  for (const double rate : {60.0, 250.0, 1000.0}) {
    Labelled d = synthetic(rate, 20, 11);
    Degradation g;
    g.extra_noise_deg = 0.05;
    g.dropouts_per_s = 3;
    degrade(d.samples, g);
    // Irregular timing: jitter every time by up to +-30 % of a period (still increasing).
    std::mt19937_64 rng(9);
    std::uniform_real_distribution<double> jitter(-0.3, 0.3);
    for (auto& x : d.samples) x.t_s += jitter(rng) / rate;
    for (const auto& m : method_names()) {
      SCOPED_TRACE(m + " at " + std::to_string(rate));
      const auto online = run_online(m, d.samples, rate);
      EXPECT_EQ(online, classify_all(m, rate, d.samples));
    }
  }
}

TEST(Classify, LatencyHoldsAcrossLongPauses) {
  // Timestamps that jump (a tracker pausing for seconds) must release everything before them.
  Script sc;
  sc.rate = 250;
  auto s = sample(sc, 2.0, [](double t) { return saccade_at(t, 0.25, 5); });
  for (std::size_t i = 100; i < s.size(); ++i) s[i].t_s += 5.0;
  for (std::size_t i = 300; i < s.size(); ++i) s[i].t_s += 100.0;
  for (const auto& m : method_names()) run_online(m, s, 250);
}

TEST(Classify, GarbageInputHasDefinedLabels) {
  std::vector<Sample> s;
  for (int i = 0; i < 50; ++i) s.push_back({0.5, 1, 1, true, 0});              // constant timestamps
  for (int i = 0; i < 50; ++i) s.push_back({0.5 - i * 0.01, 1, 1, true, 0});   // time going backwards
  s.push_back({kNaN, 0, 0, true, 0});
  s.push_back({std::numeric_limits<double>::infinity(), 0, 0, true, 0});
  for (int i = 0; i < 50; ++i) s.push_back({1.0 + i * 0.004, 1e300 * (i % 2 ? 1 : -1), -1e308, true, 0});  // huge
  for (int i = 0; i < 50; ++i) s.push_back({1.2 + i * 0.004, 1e-300, std::numeric_limits<double>::denorm_min(), true,
                                            std::numeric_limits<double>::infinity()});
  for (int i = 0; i < 50; ++i) s.push_back({1e300 + i * 1e290, 0, 0, true, -1});  // huge times
  s.push_back({-1e300, 0, 0, true, kNaN});
  for (const auto& m : method_names()) {
    SCOPED_TRACE(m);
    const auto l = run_online(m, s, 250);
    ASSERT_EQ(l.size(), s.size());
    for (std::size_t i = 1; i < 102; ++i) EXPECT_EQ(l[i], Label::Unknown) << i;  // times not after the last
    for (std::size_t i = 102; i < 152; ++i) {  // no gaze direction: a loss (blink or lost)
      EXPECT_TRUE(l[i] == Label::Lost || l[i] == Label::Blink) << i << " " << to_string(l[i]);
    }
    EXPECT_EQ(l.back(), Label::Unknown);
    EXPECT_EQ(l, classify_all(m, 250, s));
  }
  for (const auto& m : method_names()) EXPECT_TRUE(classify_all(m, 250, {}).empty());
}

// Issue 23 item 12: gaze that jumped back and forth faster than any eye moves (80 deg in 4 ms, or
// in 1 us) was labelled fixation by the noise-adaptive methods, whose noise estimate swallowed it.
// Above 1000 deg/s a sample is noise (Nystrom & Holmqvist 2010): lost, never a fixation; a single
// such spike inside a fixation is bridged (where the method fills gaps) and the fixation goes on.
TEST(Classify, ImpossibleSpeedIsNoiseNotFixation) {
  for (const double dt : {0.004, 1e-6}) {
    std::vector<Sample> s;
    for (int i = 0; i < 200; ++i) s.push_back({1.0 + i * dt, i % 2 ? 80.0 : -80.0, 0, true, 0});
    for (const auto& m : method_names()) {
      SCOPED_TRACE(m + " every " + std::to_string(dt) + " s");
      const auto l = run_online(m, s, 250);
      ASSERT_EQ(l.size(), s.size());
      for (std::size_t i = 1; i < l.size(); ++i) EXPECT_EQ(l[i], Label::Lost) << i << " " << to_string(l[i]);
    }
  }
  std::vector<Sample> spike;
  for (int i = 0; i < 200; ++i) spike.push_back({1.0 + i * 0.004, i == 100 ? 40.0 : 0.0, 0, true, 0});
  for (const auto& m : method_names()) {
    SCOPED_TRACE(m + " spike");
    const auto l = run_online(m, spike, 250);
    ASSERT_EQ(l.size(), spike.size());
    // The spike and the jump back from it are bridged (fixation) or, by lee2009 which fills no gaps,
    // lost, and its first sample after a loss is unknown; never a saccade.
    for (const std::size_t i : {100u, 101u}) EXPECT_TRUE(l[i] == Label::Fixation || l[i] == Label::Lost) << to_string(l[i]);
    EXPECT_TRUE(l[102] == Label::Fixation || l[102] == Label::Unknown) << to_string(l[102]);
    for (std::size_t i = 60; i < 140; ++i) {
      if (i >= 100 && i <= 102) continue;
      EXPECT_EQ(l[i], Label::Fixation) << i << " " << to_string(l[i]);
    }
  }
}

// --- accuracy on labelled synthetic gaze -------------------------------------------------------------
//
// Thresholds (CLASSIFY.md explains them): Landis & Koch call kappa > 0.8 "almost perfect" and
// 0.6-0.8 "substantial". Human expert coders agree with each other at about 0.9 on fixations and
// saccades and lower on pursuit (Andersson et al. 2017, Startsev et al. 2019). We require of the
// default method, at a lab tracker's rate with realistic noise and dropouts (250 Hz, +0.05 deg,
// 2 dropouts/s): fixation and saccade >= 0.85, pursuit >= 0.7, blink >= 0.8; on a 60 Hz remote
// tracker with 0.3 deg noise: fixation and saccade >= 0.7. The thresholds sit below the measured
// values (CLASSIFY.md table) with margin for seeds; they were not used to tune any parameter.

namespace {
struct Kappas {
  double fixation, saccade, pursuit, blink;
};
Kappas measure(const std::string& method, double rate, double extra_noise, double drops) {
  std::vector<Label> truth, predicted;
  for (std::uint64_t seed = 21; seed < 23; ++seed) {
    Labelled d = synthetic(rate, 60, seed);
    Degradation g;
    g.extra_noise_deg = extra_noise;
    g.dropouts_per_s = drops;
    g.seed = seed * 7;
    degrade(d.samples, g);
    const auto p = classify_all(method, rate, d.samples);
    truth.insert(truth.end(), d.truth.begin(), d.truth.end());
    predicted.insert(predicted.end(), p.begin(), p.end());
  }
  return {class_kappa(truth, predicted, Label::Fixation), class_kappa(truth, predicted, Label::Saccade),
          class_kappa(truth, predicted, Label::Pursuit), class_kappa(truth, predicted, Label::Blink)};
}
}  // namespace

TEST(ClassifyAccuracy, DefaultAt250HzRealisticNoise) {
  const Kappas k = measure("ivvt", 250, 0.05, 2);
  EXPECT_GE(k.fixation, 0.85);
  EXPECT_GE(k.saccade, 0.85);
  EXPECT_GE(k.pursuit, 0.70);
  EXPECT_GE(k.blink, 0.80);
}

TEST(ClassifyAccuracy, DefaultAt60HzRemoteTracker) {
  const Kappas k = measure("ivvt", 60, 0.3, 2);
  EXPECT_GE(k.fixation, 0.70);
  EXPECT_GE(k.saccade, 0.70);
}

TEST(ClassifyAccuracy, DefaultAt1000HzNoisy) {
  const Kappas k = measure("ivvt", 1000, 0.1, 2);
  EXPECT_GE(k.fixation, 0.80);
  EXPECT_GE(k.saccade, 0.80);
  EXPECT_GE(k.pursuit, 0.60);
}

TEST(ClassifyAccuracy, IvtAndIdtFixationSaccade) {
  const Kappas v = measure("ivt", 250, 0.05, 2);
  EXPECT_GE(v.saccade, 0.80);
  const Kappas d = measure("idt", 250, 0.05, 2);
  EXPECT_GE(d.fixation, 0.5);
}

// --- fovea-ctl classify -----------------------------------------------------------------------------

#ifdef FOVEA_CTL_PATH
namespace {
namespace fs = std::filesystem;
struct Ctl {
  fs::path dir = fs::temp_directory_path() / ("fovea_classify_" + std::to_string(::getpid()));
  Ctl() { fs::create_directories(dir); }
  ~Ctl() {
    std::error_code ec;
    fs::remove_all(dir, ec);
  }
  std::string write(const std::string& name, const std::string& text) {
    std::ofstream(dir / name) << text;
    return (dir / name).string();
  }
  // Runs fovea-ctl classify; returns the exit status and fills `err` with stderr.
  int run(const std::string& args, std::string& err) {
    const std::string errf = (dir / "stderr.txt").string();
    const std::string cmd = std::string(FOVEA_CTL_PATH) + " classify " + args + " 2> " + errf;
    const int rc = std::system(cmd.c_str());
    std::ifstream e(errf);
    std::stringstream ss;
    ss << e.rdbuf();
    err = ss.str();
    return WIFEXITED(rc) ? WEXITSTATUS(rc) : -1;
  }
  static std::string read(const std::string& p) {
    std::ifstream f(p);
    std::stringstream ss;
    ss << f.rdbuf();
    return ss.str();
  }
};
const char* kGeometry = " 250 1920 1080 531 299 650";
}  // namespace

TEST(ClassifyCli, WritesOneLabelPerRow) {
  Ctl c;
  std::string csv = "t_ms,x_px,y_px\n";
  for (int i = 0; i < 500; ++i) {
    const double x = i < 250 ? 800 : 1100;  // a jump of ~ 300 px (about 5 deg) at 1 s
    csv += std::to_string(i * 4) + "," + (i >= 400 && i < 420 ? std::string("nan") : std::to_string(x)) + ",540\n";
  }
  const std::string in = c.write("in.csv", csv), out = (c.dir / "out.csv").string();
  std::string err;
  ASSERT_EQ(c.run(in + " " + out + kGeometry, err), 0) << err;
  std::istringstream lines(Ctl::read(out));
  std::string line;
  std::getline(lines, line);
  EXPECT_EQ(line, "t_ms,label");
  int n = 0;
  std::map<std::string, int> counts;
  while (std::getline(lines, line)) {
    const auto comma = line.find(',');
    ASSERT_NE(comma, std::string::npos);
    EXPECT_EQ(line.substr(0, comma), std::to_string(n * 4));
    ++counts[line.substr(comma + 1)];
    ++n;
  }
  EXPECT_EQ(n, 500);
  EXPECT_GT(counts["fixation"], 400);
  EXPECT_GE(counts["saccade"], 1);
  // Refuses to overwrite; --force replaces; every method by name.
  EXPECT_EQ(c.run(in + " " + out + kGeometry, err), 1);
  EXPECT_NE(err.find("already exists"), std::string::npos) << err;
  for (const auto& m : method_names()) EXPECT_EQ(c.run(in + " " + out + kGeometry + " --force --method " + m, err), 0) << err;
  EXPECT_NE(c.run(in + " " + out + kGeometry + " --force --method nope", err), 0);
}

TEST(ClassifyCli, MalformedInputNamesTheLineAndWritesNothing) {
  Ctl c;
  const std::string out = (c.dir / "out.csv").string();
  const std::pair<std::string, std::string> cases[] = {
      {"t,x,y\n1,2,3\n", ":1: header"},
      {"t_ms,x_px,y_px\n0,1,2\n4,1\n", ":3: 2 fields"},
      {"t_ms,x_px,y_px\n0,1,2\n4,abc,2\n", ":3: x_px \"abc\""},
      {"t_ms,x_px,y_px\n0,1,2\nnan,1,2\n", ":3: t_ms"},
      {"t_ms,x_px,y_px\n0,1,2\n8,1,2\n4,1,2\n", ":4: t_ms 4 is not after"},
      {"t_ms,x_px,y_px\n0,1,2\n0,1,2\n", ":3: t_ms 0 is not after"},
      {"t_ms,x_px,y_px\n0,1,2\n4,1,inf\n", ":3: y_px"},
      {"", "empty file"},
  };
  for (const auto& [text, want] : cases) {
    const std::string in = c.write("bad.csv", text);
    std::string err;
    EXPECT_EQ(c.run(in + " " + out + kGeometry, err), 1) << text;
    EXPECT_NE(err.find(want), std::string::npos) << "want '" << want << "' in: " << err;
    EXPECT_FALSE(fs::exists(out)) << text;
    for (const auto& e : fs::directory_iterator(c.dir)) {
      EXPECT_EQ(e.path().filename().string().find(".partial"), std::string::npos) << "temp file left behind";
    }
  }
  std::string err;
  const std::string in = c.write("ok.csv", "t_ms,x_px,y_px\n0,1,2\n");
  EXPECT_EQ(c.run(in + " " + out + " 250 1920 1080 0 299 650", err), 1);
  EXPECT_NE(err.find("width_m"), std::string::npos) << err;
  EXPECT_EQ(c.run(in + " " + out + " -5 1920 1080 531 299 650", err), 1);
  EXPECT_NE(err.find("RATE_HZ"), std::string::npos) << err;
}

// Issue 25, goal 4: when each label became final, as the daemon would have it.
TEST(ClassifyCli, FinalTimesSayWhenEachLabelWasKnown) {
  Ctl c;
  std::string csv = "t_ms,x_px,y_px\n";
  for (int i = 0; i < 500; ++i) csv += std::to_string(i * 4) + "," + (i < 250 ? "800" : "1100") + ",540\n";
  const std::string in = c.write("in.csv", csv), out = (c.dir / "out.csv").string();
  std::string err;
  ASSERT_EQ(c.run(in + " " + out + kGeometry + " --final-times", err), 0) << err;
  std::istringstream lines(Ctl::read(out));
  std::string line;
  std::getline(lines, line);
  EXPECT_EQ(line, "t_ms,label,final_ms");
  const double bound_ms = make_classifier("ivvt", 250)->latency_s() * 1000;
  int n = 0, at_end = 0;
  double last_final = 0;
  while (std::getline(lines, line)) {
    const auto a = line.find(','), b = line.rfind(',');
    const double t = std::stod(line.substr(0, a)), final_ms = std::stod(line.substr(b + 1));
    EXPECT_GE(final_ms, t) << line;
    EXPECT_GE(final_ms, last_final) << "labels become final in order";
    last_final = final_ms;
    if (final_ms == 1996) {
      ++at_end;  // the flush at the end of the file
    } else {
      EXPECT_LE(final_ms - t, bound_ms + 1e-6) << line;
    }
    ++n;
  }
  EXPECT_EQ(n, 500);
  EXPECT_LT(at_end, 100) << "only the last samples wait for the end of the file";
}

// Issue 25: real exports hold NaN, empty, zero or reset timestamps, or none at all.
TEST(ClassifyCli, RenumberNumbersBrokenTimesAtTheRateAndSaysHowMany) {
  Ctl c;
  const std::string out = (c.dir / "out.csv").string();
  // 250 Hz: 4 ms apart. Row 3 NaN, row 4 empty, row 5 zero, rows 6.. a reset clock (0.5, 1, ...).
  const std::string in = c.write("broken.csv",
                                 "t_ms,x_px,y_px\n100,960,540\n104,960,540\nNaN,960,540\n,960,540\n0,960,540\n"
                                 "0.5,960,540\n1,960,540\n130,960,540\n");
  std::string err;
  EXPECT_EQ(c.run(in + " " + out + kGeometry, err), 1) << "without --renumber a broken time is an error";
  EXPECT_NE(err.find("--renumber"), std::string::npos) << "the error should name the way out: " << err;
  ASSERT_EQ(c.run(in + " " + out + kGeometry + " --renumber", err), 0) << err;
  EXPECT_NE(err.find("renumbered 5 of 8 rows at 250 Hz"), std::string::npos) << err;
  const auto times_in = [](const std::string& path) {
    std::vector<std::string> times;
    std::istringstream lines(Ctl::read(path));
    std::string line;
    std::getline(lines, line);
    while (std::getline(lines, line)) times.push_back(line.substr(0, line.find(',')));
    return times;
  };
  const std::vector<std::string> want = {"100", "104", "108", "112", "116", "120", "124", "130"};
  EXPECT_EQ(times_in(out), want) << "good times echoed as written, broken ones numbered 4 ms after the previous row";

  // No time column at all: every row numbered from 0.
  const std::string bare = c.write("bare.csv", "x_px,y_px\n960,540\n961,540\nnan,nan\n962,540\n");
  ASSERT_EQ(c.run(bare + " " + out + kGeometry + " --renumber --force", err), 0) << err;
  EXPECT_NE(err.find("renumbered 4 of 4 rows"), std::string::npos) << err;
  EXPECT_EQ(times_in(out), (std::vector<std::string>{"0", "4", "8", "12"}));
  EXPECT_EQ(c.run(bare + " " + out + kGeometry + " --force", err), 1) << "x_px,y_px needs --renumber";
  EXPECT_NE(err.find("with --renumber"), std::string::npos) << err;
  // Positions are still checked.
  const std::string bad = c.write("bad.csv", "x_px,y_px\n960,540\n961\n");
  EXPECT_EQ(c.run(bad + " " + out + kGeometry + " --renumber --force", err), 1);
  EXPECT_NE(err.find(":3: 1 fields, expected 2 (x_px,y_px)"), std::string::npos) << err;
}

// Real exports mark a lost sample with an empty cell or a fixed point (often 0,0): read as gaze, the
// point is a jump to the corner and back, two false saccades around every blink.
TEST(ClassifyCli, EmptyCellsAndTheLostAtPointAreLostSamples) {
  Ctl c;
  const std::string out = (c.dir / "out.csv").string();
  // 250 Hz fixation at the centre with a 100 ms loss in the middle, written three ways.
  const auto recording = [](const std::string& lost_cells) {
    std::string csv = "t_ms,x_px,y_px\n";
    for (int i = 0; i < 500; ++i) {
      csv += std::to_string(i * 4) + "," + (i >= 250 && i < 275 ? lost_cells : std::string("960,540")) + "\n";
    }
    return csv;
  };
  const auto labels_of = [](const std::string& path) {
    std::map<std::string, int> counts;
    std::istringstream lines(Ctl::read(path));
    std::string line;
    std::getline(lines, line);
    while (std::getline(lines, line)) ++counts[line.substr(line.find(',') + 1)];
    return counts;
  };
  std::string err;
  const std::string nan_in = c.write("nan.csv", recording("nan,nan"));
  ASSERT_EQ(c.run(nan_in + " " + out + kGeometry, err), 0) << err;
  const std::map<std::string, int> want = labels_of(out);
  EXPECT_EQ(want.count("saccade"), 0u);
  EXPECT_NE(err.find("25 rows without a gaze point"), std::string::npos) << err;

  const std::string empty_in = c.write("empty.csv", recording(","));
  ASSERT_EQ(c.run(empty_in + " " + out + kGeometry + " --force", err), 0) << err;
  EXPECT_EQ(labels_of(out), want) << "an empty cell is a lost sample, as nan is";
  EXPECT_NE(err.find("25 rows without a gaze point"), std::string::npos) << err;

  const std::string zero_in = c.write("zero.csv", recording("0,0"));
  ASSERT_EQ(c.run(zero_in + " " + out + kGeometry + " --force", err), 0) << err;
  EXPECT_NE(labels_of(out), want) << "without --lost-at, 0,0 is gaze at the corner, not lost";
  ASSERT_EQ(c.run(zero_in + " " + out + kGeometry + " --force --lost-at 0,0", err), 0) << err;
  EXPECT_EQ(labels_of(out), want) << "with --lost-at 0,0 those rows are lost";
  EXPECT_NE(err.find("0 rows without a gaze point (x_px or y_px nan or empty) and 25 at the --lost-at point 0,0"),
            std::string::npos)
      << err;
  // Only the exact point: gaze that passes near it stays gaze.
  ASSERT_EQ(c.run(zero_in + " " + out + kGeometry + " --force --lost-at 0,0.5", err), 0) << err;
  EXPECT_NE(err.find("and 0 at the --lost-at point"), std::string::npos) << err;

  for (const char* bad : {"0", "0,0,0", "a,0", "0,inf", ""}) {
    EXPECT_EQ(c.run(zero_in + " " + out + kGeometry + " --force --lost-at '" + bad + "'", err), 1) << bad;
    EXPECT_NE(err.find("--lost-at"), std::string::npos) << bad << ": " << err;
  }
}

// Issue 23 item 12: a 50 MB bad field was echoed whole; control characters reached the terminal.
TEST(ClassifyCli, ABadFieldIsEchoedShortAndEscaped) {
  Ctl c;
  const std::string out = (c.dir / "out.csv").string();
  const std::string in = c.write("bad.csv", "t_ms,x_px,y_px\n0,1,2\n4,\x1b[2J" + std::string(5'000'000, '9') + "x,2\n");
  std::string err;
  EXPECT_EQ(c.run(in + " " + out + kGeometry, err), 1);
  EXPECT_LT(err.size(), 400u) << "the field was echoed whole";
  EXPECT_EQ(err.find('\x1b'), std::string::npos);
  EXPECT_NE(err.find(":3: x_px \"\\x1b[2J999"), std::string::npos) << err.substr(0, 300);
}
#endif

// Issue 25: the provisional events the daemon would send, per row, beside the final labels.
TEST(ClassifyCli, ProvisionalSaysEachEventOnTheRowThatShowedItAndCountsRetractions) {
  Ctl c;
  std::string csv = "t_ms,x_px,y_px\n";
  // 1000 Hz; a 10 deg minimum-jerk saccade (43 ms) at 500 ms, in pixels of kGeometry's screen.
  const auto geometry = protocol::DisplayGeometry{};
  for (int i = 0; i < 1000; ++i) {
    const double deg = saccade_at(i / 1000.0, 0.5, 10).first;
    const auto norm = protocol::degrees_to_normalized(geometry, {deg, 0});
    csv += std::to_string(i) + "," + std::to_string(norm.x * geometry.width_px) + ",540\n";
  }
  const std::string in = c.write("in.csv", csv), out = (c.dir / "out.csv").string();
  std::string err;
  ASSERT_EQ(c.run(in + " " + out + " 1000 1920 1080 531.3 298.9 650 --provisional", err), 0) << err;
  std::istringstream lines(Ctl::read(out));
  std::string line;
  std::getline(lines, line);
  EXPECT_EQ(line, "t_ms,label,provisional");
  std::vector<std::pair<int, std::string>> cells;
  for (int row = 0; std::getline(lines, line); ++row) {
    const std::string cell = line.substr(line.rfind(',') + 1);
    if (!cell.empty()) cells.emplace_back(row, cell);
  }
  ASSERT_EQ(cells.size(), 2u) << "the onset on one row, the landing (end and fixation start) on another";
  EXPECT_EQ(cells[0].second.rfind("saccade_start@", 0), 0u) << cells[0].second;
  EXPECT_GE(cells[0].first, 500);
  EXPECT_LE(cells[0].first, 515) << "said within 15 ms of the onset";
  EXPECT_NE(cells[1].second.find("saccade_end@"), std::string::npos) << cells[1].second;
  EXPECT_NE(cells[1].second.find(";fixation_start@"), std::string::npos) << cells[1].second;
  EXPECT_LE(cells[1].first, 543 + 20) << "landing said within 20 ms";
  EXPECT_NE(err.find("3 provisional events, 3 confirmed and 0 retracted"), std::string::npos) << err;
}
