// SPDX-License-Identifier: Apache-2.0
// The learned method's second stage (issue 43): the context features (context.h). The two-stage
// model bundle's tests are in test_classify_trees.cpp.
#include <gtest/gtest.h>

#include <cmath>
#include <deque>
#include <string>
#include <vector>

#include "classify/context.h"
#include "classify/features.h"
#include "classify/trees_core.h"

using namespace fovea::trackerd::classify;

namespace {

const std::vector<std::string> kClasses = {"fixation", "saccade"};
constexpr std::size_t kK = 2;

std::size_t at(const std::string& name) {
  const auto names = context_feature_names(kClasses);
  const auto it = std::find(names.begin(), names.end(), name);
  if (it == names.end()) throw std::out_of_range(name);
  return static_cast<std::size_t>(it - names.begin());
}

// 250 Hz for `n` samples from `origin` s; p_fixation = i / 1000 (so a window's mean is its middle
// sample's), and no gaze at the samples in `lost`.
std::deque<ContextSample> stream(std::size_t n, const std::vector<std::size_t>& lost = {}, double origin = 10.0) {
  std::deque<ContextSample> buf;
  for (std::size_t i = 0; i < n; ++i) {
    ContextSample s;
    s.t = origin + static_cast<double>(i) * 0.004;
    s.gaze = std::find(lost.begin(), lost.end(), i) == lost.end();
    s.p[0] = static_cast<double>(i) / 1000.0;
    s.p[1] = 1 - s.p[0];
    s.frame.fill(0.25f);
    push_context(buf, s, kK);
  }
  return buf;
}

std::vector<float> features_of(const std::deque<ContextSample>& buf, std::size_t i, double lookahead) {
  std::vector<float> f(context_feature_names(kClasses).size());
  context_features(buf, i, kK, lookahead, f.data());
  return f;
}

}  // namespace

TEST(Context, NamesAndHowFarEachLooksAhead) {
  const auto names = context_feature_names(kClasses);
  EXPECT_EQ(names.size(), kK + 2 * kContextOffsetsS.size() * kK + 2 * kContextWindowsS.size() * (kK + 1) +
                              static_cast<std::size_t>(kFeatureCount));
  EXPECT_LE(names.size(), kMaxContextFeatures);
  EXPECT_EQ(names.front(), "p_fixation");
  EXPECT_EQ(names.back(), feature_names().back());
  EXPECT_DOUBLE_EQ(context_feature_reach_s("p_saccade_p32ms"), 0.032);
  EXPECT_DOUBLE_EQ(context_feature_reach_s("gaze_p512ms"), 0.512);
  EXPECT_DOUBLE_EQ(context_feature_reach_s("mean_fixation_m128ms"), 0.0);
  EXPECT_DOUBLE_EQ(context_feature_reach_s("speed_c_4ms"), 0.0);   // a frame feature
  EXPECT_DOUBLE_EQ(context_feature_reach_s("p_fixation"), 0.0);
  EXPECT_DOUBLE_EQ(context_feature_reach_s("cos_p_ms"), 0.0);      // not a number of ms
}

TEST(Context, OffsetsAndWindowsReadTheRightSamples) {
  const auto buf = stream(400);
  const auto f = features_of(buf, 200, kContextReachS);
  EXPECT_FLOAT_EQ(f[at("p_fixation")], 0.200f);
  EXPECT_FLOAT_EQ(f[at("p_fixation_m8ms")], 0.198f);   // 2 samples back
  EXPECT_FLOAT_EQ(f[at("p_fixation_p512ms")], 0.328f);  // 128 ahead
  EXPECT_FLOAT_EQ(f[at("p_saccade_m128ms")], 1 - 0.168f);
  // [t - 32 ms, t): samples 192..199, mean 195.5; (t, t + 32 ms]: 201..208, mean 204.5
  EXPECT_NEAR(f[at("mean_fixation_m32ms")], 0.1955, 1e-6);
  EXPECT_NEAR(f[at("mean_fixation_p32ms")], 0.2045, 1e-6);
  EXPECT_NEAR(f[at("mean_saccade_p128ms")], 1 - 0.2165, 1e-6);  // 201..232
  EXPECT_FLOAT_EQ(f[at("gaze_m512ms")], 1.0f);
  EXPECT_FLOAT_EQ(f[at("speed_c_4ms")], 0.25f);  // the frame features ride along
}

// A sample exactly D or D/2 away, or at a window's edge, is the same sample whatever the clock's
// origin (the times are doubles: 32 ms is 0.032000000000001 s from one origin, 0.031999999999998
// from another).
TEST(Context, TheEdgesDoNotDependOnWhereTheClockStarts) {
  const auto reference = stream(400, {}, 0.0);
  for (const double origin : {0.1, 10.0, 1000.003, 86400.77}) {
    const auto buf = stream(400, {}, origin);
    for (std::size_t i = 0; i < buf.size(); i += 7) {
      const auto want = features_of(reference, i, kContextReachS), got = features_of(buf, i, kContextReachS);
      for (std::size_t k = 0; k < want.size(); ++k) {
        if (std::isnan(want[k])) {
          ASSERT_TRUE(std::isnan(got[k])) << "sample " << i << " from " << origin << " s: " << k;
        } else {
          ASSERT_NEAR(got[k], want[k], 1e-6) << "sample " << i << " from " << origin << " s: " << k;
        }
      }
    }
  }
  // Half of D away is not within (D/2, D]: with 4 ms between samples and the one 8 ms back missing
  // from the stream, the one 4 ms back is no stand-in for it, from any origin.
  for (const double origin : {0.0, 0.1, 10.0, 1000.003, 86400.77}) {
    std::deque<ContextSample> gap = stream(30, {}, origin);
    gap.erase(gap.begin() + 18);
    std::deque<ContextSample> rebuilt;  // the running totals again, without it
    for (ContextSample s : gap) push_context(rebuilt, s, kK);
    EXPECT_TRUE(std::isnan(features_of(rebuilt, 19, kContextReachS)[at("p_fixation_m8ms")])) << origin;
    EXPECT_FLOAT_EQ(features_of(rebuilt, 19, kContextReachS)[at("p_fixation_m16ms")], 0.016f) << origin;
  }
}

TEST(Context, NothingLooksFurtherAheadThanTheLookAhead) {
  const auto buf = stream(400);
  const auto full = features_of(buf, 200, kContextReachS);
  const auto online = features_of(buf, 200, 0.032);
  const auto names = context_feature_names(kClasses);
  for (std::size_t k = 0; k < names.size(); ++k) {
    if (context_feature_reach_s(names[k]) > 0.032) {
      EXPECT_TRUE(std::isnan(online[k])) << names[k];
    } else {
      EXPECT_EQ(online[k], full[k]) << names[k];  // and the rest is the same numbers
    }
  }
}

TEST(Context, LossesAndTheStreamsEnds) {
  const auto buf = stream(100, {48, 49, 50, 51});
  const auto f = features_of(buf, 46, kContextReachS);
  EXPECT_TRUE(std::isnan(f[at("p_fixation_p8ms")]));  // sample 48 has no gaze
  // (t, t + 32 ms]: 47..54 of which 48-51 lost: the mean over the gaze ones, the share of them
  EXPECT_NEAR(f[at("mean_fixation_p32ms")], (0.047 + 0.052 + 0.053 + 0.054) / 4, 1e-6);
  EXPECT_FLOAT_EQ(f[at("gaze_p32ms")], 0.5f);
  // D before: the furthest sample within (D/2, D]; 46 is 184 ms into the stream.
  EXPECT_TRUE(std::isnan(f[at("p_fixation_m512ms")]));  // none: before the stream's start
  EXPECT_FLOAT_EQ(f[at("p_fixation_m256ms")], 0.0f);     // the stream's first sample
  EXPECT_FLOAT_EQ(f[at("p_fixation_m128ms")], 0.014f);   // 46 - 32
  EXPECT_TRUE(std::isnan(f[at("p_fixation_p512ms")]));  // after its end
  const auto first = features_of(buf, 0, kContextReachS);
  EXPECT_TRUE(std::isnan(first[at("mean_fixation_m32ms")]));  // an empty window
  EXPECT_TRUE(std::isnan(first[at("gaze_m32ms")]));
  const auto lost = features_of(buf, 49, kContextReachS);
  EXPECT_TRUE(std::isnan(lost[at("p_fixation")]));
  EXPECT_FLOAT_EQ(lost[at("p_fixation_m8ms")], 0.047f);
}

TEST(Context, APauseInTheStreamIsNoNeighbour) {
  std::deque<ContextSample> buf = stream(50);
  ContextSample late;
  late.t = buf.back().t + 5.0;  // the tracker paused for 5 s
  late.gaze = true;
  push_context(buf, late, kK);
  const auto f = features_of(buf, 49, kContextReachS);
  EXPECT_TRUE(std::isnan(f[at("p_fixation_p512ms")]));
  EXPECT_TRUE(std::isnan(f[at("mean_fixation_p512ms")]));
}

namespace {

// Every sample's context features as the built-in model's online (or offline) stage reads them, or
// (context_only) with the whole reach, as that chain's stage was trained on them.
std::vector<std::vector<float>> stage_inputs(const std::vector<Sample>& samples, bool offline, bool context_only = false) {
  std::vector<std::vector<float>> rows(samples.size());
  GbtOptions o;
  o.offline = offline;
  o.trees_only = true;
  o.context_only = context_only;
  o.context_sink = [&](std::uint64_t index, const float* f) {
    const auto width = context_feature_names(builtin_gbt_model()->frame().trees().class_names()).size();
    rows[index].assign(f, f + width);
  };
  auto pipeline = make_trees_pipeline(builtin_gbt_model(), fovea::protocol::DisplayGeometry{}, std::move(o));
  std::vector<Labeled> out;
  for (const Sample& s : samples) pipeline->push(s, out);
  pipeline->flush(out);
  return rows;
}

}  // namespace

// What bench/train_classifier.py trains the daemon's stage on (the offline features with every
// column that reaches beyond the look-ahead blank) must be what the daemon computes, sample by
// sample, also where times are sums that round (t += 1/60 s) and rates do not divide the offsets.
TEST(Context, TheDaemonsStageReadsWhatItWasTrainedOn) {
  const auto model = builtin_gbt_model();
  ASSERT_TRUE(model->context(false));
  const auto names = context_feature_names(model->frame().trees().class_names());
  for (double rate : {60.0, 250.0, 1000.0}) {
    std::vector<Sample> s;
    double t = 3.0;
    for (int k = 0; k < static_cast<int>(4 * rate); ++k, t += 1 / rate) {
      const double phase = std::fmod(t, 1.0);  // fixation, a saccade, a slow pursuit, again
      const double x = phase < 0.4 ? 0.0 : phase < 0.45 ? 160 * (phase - 0.4) : 8 + 10 * (phase - 0.45);
      s.push_back({t, x, 1.0, k % 97 != 50});  // and a lost sample now and then
    }
    const auto online = stage_inputs(s, false), full = stage_inputs(s, false, true);
    std::size_t compared = 0;
    for (std::size_t i = 0; i < s.size(); ++i) {
      ASSERT_EQ(online[i].size(), names.size()) << "sample " << i << " at " << rate << " Hz was not staged";
      for (std::size_t k = 0; k < names.size(); ++k) {
        const bool blank = context_feature_reach_s(names[k]) > model->lookahead_s(false) + 1e-9;
        const float want = blank ? std::nanf("") : full[i][k];
        ASSERT_TRUE(std::isnan(want) ? std::isnan(online[i][k]) : online[i][k] == want)
            << names[k] << " of sample " << i << " at " << rate << " Hz: " << online[i][k] << " online, " << want;
        ++compared;
      }
    }
    EXPECT_GT(compared, s.size() * names.size() - 1);
  }
}

// The cursor (what the daemon's stage uses) finds what the searches find, sample after sample,
// with the rate changing, a pause, losses, samples arriving at the end and leaving at the front,
// at both look-aheads.
TEST(Context, TheCursorFindsWhatTheSearchFinds) {
  std::vector<double> times;
  double t = 3.0;
  for (int i = 0; i < 1500; ++i) {
    t += i < 400 ? 0.004 : i < 900 ? 0.001 : i < 1000 ? 1.0 / 60 : 0.002;
    if (i == 1200) t += 0.3;  // a pause
    times.push_back(t);
  }
  for (double lookahead : {0.032, kContextReachS}) {
    std::deque<ContextSample> buf;
    ContextCursor cursor;
    std::size_t next = 0, pushed = 0, compared = 0;
    while (next < times.size()) {
      // Push ahead of the sample to be featured (up to its look-ahead, as the stage does), in bursts.
      while (pushed < times.size() && (pushed < next + buf.size() / 8 + 1 || times[pushed] <= times[next] + lookahead)) {
        ContextSample s;
        s.t = times[pushed];
        s.gaze = pushed % 97 != 5;
        s.p[0] = static_cast<double>(pushed % 13) / 13.0;
        s.p[1] = 1 - s.p[0];
        push_context(buf, s, kK);
        ++pushed;
      }
      const std::size_t i = buf.size() - (pushed - next);
      std::vector<float> searched = features_of(buf, i, lookahead), walked(searched.size());
      context_features(buf, i, kK, lookahead, walked.data(), &cursor);
      for (std::size_t k = 0; k < searched.size(); ++k) {
        ASSERT_TRUE(searched[k] == walked[k] || (std::isnan(searched[k]) && std::isnan(walked[k])))
            << "sample " << next << " feature " << context_feature_names(kClasses)[k];
      }
      ++compared;
      ++next;
      // Keep what the next sample reaches back to (as the stage trims), dropping in ones and twos.
      while (buf.size() > pushed - next + 2 && times[next] - buf[1].t >= kContextReachS) {
        buf.pop_front();
        cursor.dropped_front(1);
      }
    }
    EXPECT_EQ(compared, times.size());
  }
}
