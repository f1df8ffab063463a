// SPDX-License-Identifier: Apache-2.0
// The learned method's parts (issue 43): the tree format and its evaluation (trees.h), the
// multi-scale features (features.h) and the built-in model.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <deque>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "classify/classifier.h"
#include "classify/context.h"
#include "classify/features.h"
#include "classify/trees.h"
#include "classify/trees_core.h"

using namespace fovea::trackerd::classify;

namespace {

const std::vector<std::string> kTwo = {"a", "b"};

// Two classes; tree 0 (class 0): a <= 1 (NaN right) -> +2 else -1; tree 1 (class 1): b <= 0.5 (NaN
// left) -> 0 else +3.
const char* kModel = R"(# a comment
fovea-trees 1
features 2 a b
classes 2 fixation saccade
baseline 0.5 0
trees 2
tree 0 3
0 1 0 1 2 0
-1 0 0 0 0 2
-1 0 0 0 0 -1
tree 1 3
1 0.5 1 1 2 0
-1 0 0 0 0 0
-1 0 0 0 0 3
)";

// What `f` throws as std::invalid_argument ("" if nothing).
template <class F>
std::string error_of(F f) {
  try {
    f();
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "";
}

std::string parse_error(const std::string& text, const std::vector<std::string>& features = kTwo) {
  return error_of([&] { TreeEnsemble::parse(text, "m.trees", features); });
}

std::string replaced(std::string s, const std::string& from, const std::string& to) {
  s.replace(s.find(from), from.size(), to);
  return s;
}

}  // namespace

TEST(Trees, EvaluatesSplitsMissingValuesAndBaseline) {
  const TreeEnsemble m = TreeEnsemble::parse(kModel, "m.trees", kTwo);
  EXPECT_EQ(m.tree_count(), 2u);
  EXPECT_EQ(m.node_count(), 6u);
  double s[2];
  const float nan = std::nanf("");
  const auto run = [&](float a, float b) {
    const float f[2] = {a, b};
    return m.predict(f, s);
  };
  EXPECT_EQ(run(1.0f, 0.5f), 0);  // <= goes left: 0.5 + 2 against 0
  EXPECT_DOUBLE_EQ(s[0], 2.5);
  EXPECT_DOUBLE_EQ(s[1], 0.0);
  EXPECT_EQ(run(1.5f, 0.7f), 1);  // -0.5 against 3
  EXPECT_DOUBLE_EQ(s[0], -0.5);
  EXPECT_EQ(run(nan, nan), 1);  // a NaN: right in tree 0 (0.5 - 1), left in tree 1 (0)
  EXPECT_DOUBLE_EQ(s[0], -0.5);
  EXPECT_DOUBLE_EQ(s[1], 0.0);
  // scikit-learn splits numbers from NaN with the threshold inf: every number goes left.
  const TreeEnsemble inf = TreeEnsemble::parse(replaced(kModel, "0 1 0 1 2 0", "0 inf 0 1 2 0"), "m.trees", kTwo);
  const float big[2] = {3e38f, 0.0f}, missing[2] = {nan, 0.0f};
  inf.predict(big, s);
  EXPECT_DOUBLE_EQ(s[0], 2.5);
  inf.predict(missing, s);
  EXPECT_DOUBLE_EQ(s[0], -0.5);
}

// The walk compares float features with float thresholds: the largest float at or below the file's
// double, which splits every float exactly as the double does.
TEST(Trees, FloatFeaturesSplitExactlyAsAtTheFilesDoubleThreshold) {
  const TreeEnsemble m = TreeEnsemble::parse(replaced(kModel, "0 1 0 1 2 0", "0 0.1 0 1 2 0"), "m.trees", kTwo);
  double s[2];
  const float above = 0.1f;  // 0.100000001490116...: above the double 0.1
  ASSERT_GT(static_cast<double>(above), 0.1);
  const float below = std::nextafter(above, 0.0f);
  const float f_above[2] = {above, 0.0f}, f_below[2] = {below, 0.0f};
  m.predict(f_above, s);
  EXPECT_DOUBLE_EQ(s[0], -0.5);
  m.predict(f_below, s);
  EXPECT_DOUBLE_EQ(s[0], 2.5);
  // Thresholds beyond float's range: every finite float goes left of 1e300, right of -1e300.
  const float big[2] = {3e38f, 0.0f};
  TreeEnsemble::parse(replaced(kModel, "0 1 0 1 2 0", "0 1e300 0 1 2 0"), "m.trees", kTwo).predict(big, s);
  EXPECT_DOUBLE_EQ(s[0], 2.5);
  const float small[2] = {-3e38f, 0.0f};
  TreeEnsemble::parse(replaced(kModel, "0 1 0 1 2 0", "0 -1e300 0 1 2 0"), "m.trees", kTwo).predict(small, s);
  EXPECT_DOUBLE_EQ(s[0], -0.5);
}

// Deeper trees whose nodes the file lists breadth first (as scikit-learn may) walk as the file says.
TEST(Trees, NodesInAnyOrderAfterTheirParentWalkAsTheFileSays) {
  // a <= 0 ? (b <= 0 ? 1 : 2) : (b <= 5 ? 3 : 4), nodes listed root, both splits, then the leaves
  // in an order of their own.
  const std::string model = replaced(kModel, "trees 2\ntree 0 3\n0 1 0 1 2 0\n-1 0 0 0 0 2\n-1 0 0 0 0 -1\n",
                                     "trees 2\ntree 0 7\n0 0 0 1 2 0\n1 0 0 6 5 0\n1 5 0 3 4 0\n"
                                     "-1 0 0 0 0 3\n-1 0 0 0 0 4\n-1 0 0 0 0 2\n-1 0 0 0 0 1\n");
  const TreeEnsemble m = TreeEnsemble::parse(model, "m.trees", kTwo);
  EXPECT_EQ(m.node_count(), 10u);
  double s[2];
  const auto leaf = [&](float a, float b) {
    const float f[2] = {a, b};
    m.predict(f, s);
    return s[0] - 0.5;
  };
  EXPECT_DOUBLE_EQ(leaf(-1, -1), 1);
  EXPECT_DOUBLE_EQ(leaf(-1, 1), 2);
  EXPECT_DOUBLE_EQ(leaf(1, 1), 3);
  EXPECT_DOUBLE_EQ(leaf(1, 6), 4);
}

// Trees of every depth from 0 to 5 splits, each split's NaN either way, over rows with NaN: the
// scores are each tree's leaf added in the file's order, bit for bit.
TEST(Trees, ManyTreesOfUnequalDepthsScoreAsEachWalkedAlone) {
  struct Split {
    long feature;
    double threshold;
    bool missing_left;
  };
  // Tree k (class k % 3): a chain of k % 6 splits, split d on feature (k + d) % 3, going on left
  // when d is even and right when odd; split d's other child is the leaf k + 0.25 (d + 1), the
  // chain's end the leaf -k. Thresholds are drawn as the file writes them (6 decimals), so the test
  // compares with what is parsed; the leaves are exact in 6 decimals.
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-2, 2);
  std::vector<std::vector<Split>> chains;
  std::string text = "fovea-trees 1\nfeatures 3 a b c\nclasses 3 fixation saccade pursuit\nbaseline 0.1 -0.2 0.3\ntrees 21\n";
  for (int k = 0; k < 21; ++k) {
    const int depth = k % 6;
    std::vector<Split> chain;
    text += "tree " + std::to_string(k % 3) + " " + std::to_string(2 * depth + 1) + "\n";
    for (int d = 0; d < depth; ++d) {
      chain.push_back({(k + d) % 3, std::stod(std::to_string(u(rng))), (k + d) % 2 == 0});
      // Node 2d: the split; 2d + 1 its leaf; 2d + 2 where the chain goes on.
      const int leaf = 2 * d + 1, next = 2 * d + 2;
      const bool next_left = d % 2 == 0;
      text += std::to_string(chain.back().feature) + " " + std::to_string(chain.back().threshold) + " " +
              (chain.back().missing_left ? "1 " : "0 ") + std::to_string(next_left ? next : leaf) + " " +
              std::to_string(next_left ? leaf : next) + " 0\n";
      text += "-1 0 0 0 0 " + std::to_string(k + 0.25 * (d + 1)) + "\n";
    }
    text += "-1 0 0 0 0 " + std::to_string(-k) + "\n";
    chains.push_back(chain);
  }
  const TreeEnsemble m = TreeEnsemble::parse(text, "many.trees", {"a", "b", "c"});
  ASSERT_EQ(m.tree_count(), 21u);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  for (int row = 0; row < 200; ++row) {
    float f[3];
    for (float& v : f) v = row % 7 == 0 ? nan : static_cast<float>(u(rng));
    if (row % 5 == 0) f[row % 3] = nan;
    double expected[3] = {0.1, -0.2, 0.3};
    for (int k = 0; k < 21; ++k) {
      // Walk the chain: it goes on while the split sends x its way, else ends in that split's leaf.
      double leaf = -k;
      const auto& chain = chains[static_cast<std::size_t>(k)];
      for (std::size_t d = 0; d < chain.size(); ++d) {
        const float x = f[chain[d].feature];
        const bool left = std::isnan(x) ? chain[d].missing_left : static_cast<double>(x) <= chain[d].threshold;
        if (left != (d % 2 == 0)) {
          leaf = k + 0.25 * static_cast<double>(d + 1);
          break;
        }
      }
      expected[k % 3] += leaf;
    }
    double s[3];
    m.predict(f, s);
    for (int c = 0; c < 3; ++c) EXPECT_EQ(s[c], expected[c]) << "row " << row << " class " << c;
  }
}

// A model reads its features by name: one trained before the build computed more (or in another
// order) scores exactly as it did.
TEST(Trees, AModelReadsItsFeaturesByName) {
  const TreeEnsemble same = TreeEnsemble::parse(kModel, "m.trees", kTwo);
  const TreeEnsemble more = TreeEnsemble::parse(kModel, "m.trees", {"z", "b", "y", "a"});
  double s1[2], s2[2];
  for (const auto& [a, b] : std::vector<std::pair<float, float>>{{1.0f, 0.5f}, {2.0f, 0.7f}, {std::nanf(""), 0.2f}}) {
    const float two[2] = {a, b};
    const float four[4] = {-100.0f, b, 100.0f, a};
    EXPECT_EQ(same.predict(two, s1), more.predict(four, s2));
    EXPECT_EQ(s1[0], s2[0]);
    EXPECT_EQ(s1[1], s2[1]);
  }
}

TEST(Trees, DamagedModelsAreRefusedNamingTheLineAndTheProblem) {
  EXPECT_EQ(parse_error(kModel), "");
  EXPECT_EQ(parse_error(replaced(kModel, "fovea-trees 1", "fovea-trees 2")), "m.trees:2: format version is not 1");
  EXPECT_EQ(parse_error(kModel, {"a", "c"}), "m.trees:3: the model reads feature 'b', which this build does not compute: retrain it");
  EXPECT_EQ(parse_error(replaced(kModel, "features 2 a b", "features 2 a a")), "m.trees:3: the model names feature 'a' twice");
  EXPECT_EQ(parse_error(replaced(kModel, "tree 1 3", "tree 2 3")), "m.trees:11: tree class '2' is not an integer in [0, 1]");
  EXPECT_EQ(parse_error(replaced(kModel, "0 1 0 1 2 0", "0 1 0 0 2 0")),
            "m.trees:8: a split node's children must follow it");
  EXPECT_EQ(parse_error(replaced(kModel, "0 1 0 1 2 0", "0 1 0 1 3 0")), "m.trees:8: node right '3' is not an integer in [0, 2]");
  // A node that is both children (or no node's): a walk could meet it twice.
  EXPECT_EQ(parse_error(replaced(kModel, "0 1 0 1 2 0", "0 1 0 1 1 0")), "m.trees:10: tree 0: node 1 is the child of 2 splits, not 1");
  EXPECT_EQ(parse_error(replaced(kModel, "tree 0 3", "tree 0 65536")),
            "m.trees:7: node count '65536' is not an integer in [1, 65535]");
  EXPECT_EQ(parse_error(replaced(kModel, "0 1 0 1 2 0", "5 1 0 1 2 0")), "m.trees:8: node feature '5' is not an integer in [-1, 1]");
  EXPECT_EQ(parse_error(replaced(kModel, "baseline 0.5 0", "baseline 0.5 nan")), "m.trees:5: baseline 'nan' is not a finite number");
  EXPECT_EQ(parse_error(replaced(kModel, "-1 0 0 0 0 2", "-1 0 0 0 0 inf")), "m.trees:9: node value 'inf' is not a finite number");
  EXPECT_EQ(parse_error(replaced(kModel, "0 1 0 1 2 0", "0 nan 0 1 2 0")), "m.trees:8: node threshold 'nan' is not a number");
  EXPECT_EQ(parse_error(replaced(kModel, "-1 0 0 0 0 3\n", "")), "m.trees:14: ends where node feature should be");
  EXPECT_EQ(parse_error(std::string(kModel) + "tree"), "m.trees:15: unexpected text after the last tree");
  EXPECT_EQ(parse_error(replaced(kModel, "trees 2", "trees 99999999999")),
            "m.trees:6: tree count '99999999999' is not an integer in [1, 4194304]");
  EXPECT_EQ(parse_error(""), "m.trees:1: ends where fovea-trees should be");
}

TEST(Trees, AModelsClassesMustBeLabels) {
  std::string features = "features " + std::to_string(kFeatureCount);
  for (const auto& n : feature_names()) features += " " + n;
  const std::string model = replaced(kModel, "features 2 a b", features);
  EXPECT_NO_THROW(TreesModel(model, "m.trees"));
  try {
    TreesModel(replaced(model, "saccade", "wobble"), "m.trees");
    FAIL() << "a class that is no label was taken";
  } catch (const std::invalid_argument& e) {
    EXPECT_EQ(std::string(e.what()), "m.trees: class 'wobble' is none of fixation, saccade, pso, pursuit, noise, blink, lost");
  }
}

TEST(Trees, TheBuiltInModelLoadsAndMatchesThisBuildsFeatures) {
  const auto m = builtin_gbt_model();
  ASSERT_TRUE(m);
  EXPECT_GE(m->frame().trees().class_names().size(), 3u);
  EXPECT_GT(m->frame().trees().tree_count(), 0u);
}

namespace {

std::deque<Prepared> line(double rate_hz, double seconds, double vx_deg_s, double noise_deg = 0) {
  std::deque<Prepared> buf;
  std::uint64_t seed = 7;
  const auto gauss = [&] {  // a fixed pseudo-random stream, Box-Muller
    const auto u = [&] {
      seed = seed * 6364136223846793005ULL + 1442695040888963407ULL;
      return (static_cast<double>(seed >> 11) + 0.5) / 9007199254740992.0;
    };
    return std::sqrt(-2 * std::log(u())) * std::cos(2 * M_PI * u());
  };
  for (int k = 0; k < static_cast<int>(seconds * rate_hz); ++k) {
    const double t = k / rate_hz;
    buf.push_back({static_cast<std::uint64_t>(k), t, -5 + vx_deg_s * t + noise_deg * gauss(), 1 + noise_deg * gauss(),
                   Prepared::Kind::Gaze});
  }
  return buf;
}

std::size_t at(const char* name) {
  const auto& n = feature_names();
  return static_cast<std::size_t>(std::find(n.begin(), n.end(), name) - n.begin());
}

}  // namespace

TEST(Features, AnEvenMovementHasItsSpeedAtEveryScaleAndAnyRate) {
  ASSERT_EQ(feature_names().size(), static_cast<std::size_t>(kFeatureCount));
  for (double rate : {250.0, 500.0, 1000.0}) {
    const std::deque<Prepared> buf = line(rate, 1.0, 10.0);
    float f[kFeatureCount];
    sample_features(buf, buf.size() / 2, fovea::protocol::DisplayGeometry{}, f);
    for (const char* n : {"speed_c_4ms", "speed_b_16ms", "speed_f_64ms", "speed_c_256ms", "speed_b_4ms_lag4ms",
                          "speed_b_4ms_lag20ms", "speed_f_4ms_lead4ms", "speed_f_4ms_lead12ms"}) {
      EXPECT_NEAR(f[at(n)], 10.0, 0.02) << n << " at " << rate << " Hz";
    }
    EXPECT_NEAR(f[at("cos_32ms")], 1.0, 1e-5);
    EXPECT_NEAR(f[at("straight_128ms")], 1.0, 1e-5);
    // RMS spread of an even line over +-D: D v / sqrt(3).
    EXPECT_NEAR(f[at("disp_128ms")], 0.128 * 10 / std::sqrt(3.0), 0.02);
    EXPECT_FLOAT_EQ(f[at("loss_before_s")], static_cast<float>(kFeatureReachS));
    EXPECT_FLOAT_EQ(f[at("filled")], 0.0f);
    EXPECT_NEAR(f[at("noise_deg")], 0.0, 1e-4);
  }
}

TEST(Features, NoiseIsStillAndCrooked) {
  const std::deque<Prepared> buf = line(500, 1.0, 0.0, 0.05);
  float f[kFeatureCount];
  sample_features(buf, 250, fovea::protocol::DisplayGeometry{}, f);
  EXPECT_LT(f[at("straight_256ms")], 0.2f);
  EXPECT_LT(f[at("speed_c_256ms")], 0.5f);
  EXPECT_NEAR(f[at("disp_256ms")], 0.05 * std::sqrt(2.0), 0.015);
  // |second difference| of 2-D noise is Rayleigh with scale sqrt(6) sigma: median 1.1774 of that.
  EXPECT_NEAR(f[at("noise_deg")], 0.05 * std::sqrt(6.0) * 1.1774, 0.03);
}

// A still eye on a tracker that reports whole pixels: no movement, so no straight one either.
TEST(Features, StillGazeIsNoStraightMovement) {
  const std::deque<Prepared> buf = line(250, 1.0, 0.0);
  float f[kFeatureCount];
  sample_features(buf, 125, fovea::protocol::DisplayGeometry{}, f);
  for (const char* n : {"straight_4ms", "straight_256ms", "speed_c_64ms", "disp_128ms", "cos_32ms"}) {
    EXPECT_EQ(f[at(n)], 0.0f) << n;
  }
}

TEST(Features, ALossCutsTheScalesThatReachItAndSaysHowFarItIs) {
  std::deque<Prepared> buf = line(250, 1.0, 2.0);
  for (std::size_t k = 130; k < 140; ++k) buf[k].kind = Prepared::Kind::Blink;  // 520-556 ms
  float f[kFeatureCount];
  sample_features(buf, 125, fovea::protocol::DisplayGeometry{}, f);  // 500 ms: the loss starts 20 ms later
  EXPECT_TRUE(std::isfinite(f[at("speed_c_16ms")]));
  EXPECT_TRUE(std::isnan(f[at("speed_c_32ms")]));
  EXPECT_TRUE(std::isnan(f[at("disp_256ms")]));
  EXPECT_NEAR(f[at("loss_after_s")], 0.020, 1e-6);
  EXPECT_FLOAT_EQ(f[at("loss_before_s")], static_cast<float>(kFeatureReachS));
  // The 4 ms steps: the last one ahead of the sample, 12-16 ms, reaches 556 ms, into the loss.
  sample_features(buf, 126, fovea::protocol::DisplayGeometry{}, f);  // 504 ms
  EXPECT_NEAR(f[at("speed_f_4ms_lead8ms")], 2.0, 1e-3);
  EXPECT_TRUE(std::isnan(f[at("speed_f_4ms_lead12ms")]));
  sample_features(buf, 144, fovea::protocol::DisplayGeometry{}, f);  // 576 ms: 20 ms after the loss
  EXPECT_NEAR(f[at("speed_b_4ms_lag12ms")], 2.0, 1e-3);
  EXPECT_TRUE(std::isnan(f[at("speed_b_4ms_lag16ms")]));
  sample_features(buf, 135, fovea::protocol::DisplayGeometry{}, f);  // in the loss: no gaze
  EXPECT_TRUE(std::isnan(f[at("speed_c_4ms")]));
  EXPECT_TRUE(std::isnan(f[at("speed_b_4ms_lag4ms")]));
  EXPECT_TRUE(std::isnan(f[at("noise_deg")]));
  EXPECT_NEAR(f[at("loss_before_s")], 0.004, 1e-6);
}

TEST(Features, TheMatrixHasOneRowPerInputAndNanForRejectedTimes) {
  std::vector<Sample> s;
  for (int k = 0; k < 100; ++k) s.push_back({k * 0.004, 0.01 * k, 0, true});
  s[50].t_s = s[49].t_s;  // time standing still: rejected
  const std::vector<float> m = feature_matrix(s, fovea::protocol::DisplayGeometry{});
  ASSERT_EQ(m.size(), s.size() * kFeatureCount);
  EXPECT_TRUE(std::isnan(m[50 * std::size_t{kFeatureCount} + at("loss_before_s")]));
  EXPECT_NEAR(m[60 * std::size_t{kFeatureCount} + at("speed_c_8ms")], 2.5, 1e-3);  // 0.01 deg per 4 ms
}

namespace {

// A random walk with saccade-like jumps and losses, at 1000 Hz: what the window's sums must follow.
std::deque<Prepared> wander(std::size_t n, double x0 = 0) {
  std::deque<Prepared> buf;
  std::uint64_t seed = 11;
  const auto u = [&] {
    seed = seed * 6364136223846793005ULL + 1442695040888963407ULL;
    return static_cast<double>(seed >> 11) / 9007199254740992.0;
  };
  double x = x0, y = 2;
  for (std::size_t k = 0; k < n; ++k) {
    x += 0.02 * (u() - 0.5) + (u() < 0.002 ? 5 * (u() - 0.5) : 0);
    y += 0.02 * (u() - 0.5);
    const bool lost = k % 1500 >= 1400 && k % 1500 < 1420;  // 20 ms losses
    buf.push_back({k, static_cast<double>(k) * 0.001, x, y, lost ? Prepared::Kind::Blink : Prepared::Kind::Gaze});
  }
  return buf;
}

// disp and straight of buf[i] at scale d computed directly: the samples within +-d (none beyond a
// loss: the caller picks i away from them), the path through them in each step's starting frame.
std::pair<double, double> direct_disp_straight(const std::deque<Prepared>& buf, std::size_t i, double d) {
  const TangentMap tm = tangent_map(buf[i].x, buf[i].y);
  std::vector<TangentVector> p;
  double path = 0;
  std::size_t prev = 0;
  for (std::size_t k = 0; k < buf.size(); ++k) {
    if (std::abs(buf[k].t - buf[i].t) > d + 1e-9) continue;
    p.push_back(tm(buf[k].x - buf[i].x, buf[k].y - buf[i].y));
    if (p.size() > 1) {
      const TangentVector s = tangent_map(buf[prev].x, buf[prev].y)(buf[k].x - buf[prev].x, buf[k].y - buf[prev].y);
      path += std::sqrt(s.x * s.x + s.y * s.y);
    }
    prev = k;
  }
  double mx = 0, my = 0;
  for (const auto& v : p) mx += v.x, my += v.y;
  mx /= static_cast<double>(p.size()), my /= static_cast<double>(p.size());
  double ss = 0;
  for (const auto& v : p) ss += (v.x - mx) * (v.x - mx) + (v.y - my) * (v.y - my);
  // The interpolated ends lie on the samples at exactly +-d here (1000 Hz, d whole ms).
  const double net = std::hypot(p.back().x - p.front().x, p.back().y - p.front().y);
  return {std::sqrt(ss / static_cast<double>(p.size())), net / path};
}

}  // namespace

// The window's running sums give what summing the samples around each one gives, across its chunks'
// boundaries and far from where the gaze started.
TEST(Features, RunningSumsMatchTheDirectSums) {
  const std::deque<Prepared> buf = wander(5000, 30);
  FeatureWindow w;
  for (const Prepared& p : buf) w.push(p);
  float f[kFeatureCount];
  for (std::size_t i : {300u, 1023u, 1024u, 1100u, 2047u, 3300u, 4100u}) {  // 400 ms from losses
    w.features(i, fovea::protocol::DisplayGeometry{}, f);
    for (const char* scale : {"4ms", "32ms", "256ms"}) {
      const double d = std::stod(scale) / 1000;
      const auto [disp, straight] = direct_disp_straight(buf, i, d);
      EXPECT_NEAR(f[at((std::string("disp_") + scale).c_str())], disp, 1e-5 + 1e-4 * disp) << i << " " << scale;
      EXPECT_NEAR(f[at((std::string("straight_") + scale).c_str())], straight, 1e-5) << i << " " << scale;
    }
  }
}

// Online the window holds only the reach around the sample being scored; its features must be the
// very numbers of a window that holds the whole recording (so training and the daemon agree).
// With a shorter reach ahead (the daemon's own first stage) the stream scores each sample that much
// sooner, and must still compute what the whole recording gives.
TEST(Features, AStreamingWindowGivesTheWholeRecordingsNumbers) {
  const std::deque<Prepared> buf = wander(12000);
  for (double reach : {kFeatureReachS, 0.064}) {
    FeatureWindow whole, stream;
    for (const Prepared& p : buf) whole.push(p);
    std::size_t next = 0, dropped = 0, compared = 0;
    float a[kFeatureCount], b[kFeatureCount];
    for (std::size_t k = 0; k < buf.size(); ++k) {
      stream.push(buf[k]);
      for (; next < buf.size() && buf[next].t + reach <= buf[k].t; ++next) {
        whole.features(next, fovea::protocol::DisplayGeometry{}, a, reach);
        stream.features(next - dropped, fovea::protocol::DisplayGeometry{}, b, reach);
        ASSERT_EQ(0, std::memcmp(a, b, sizeof a)) << "sample " << next << ", reach " << reach;
        ++compared;
      }
      // Keep one sample beyond the reach behind the next to score, as TreesCore does.
      while (next > dropped + 1 && buf[next].t - buf[dropped + 1].t >= kFeatureReachS) {
        stream.pop_front(1);
        ++dropped;
      }
    }
    EXPECT_GT(compared, 11000u);
    EXPECT_GT(dropped, 10000u);  // past the compaction (kCompactRows) several times
  }
}

// A reach R ahead keeps every scale's past and ends the longer windows R ahead: an even movement
// still has its speed, a straight path, and the spread of the shorter segment it covers; nothing
// beyond R (not even a loss) changes a feature.
TEST(Features, AShorterReachKeepsThePastAndEndsTheLongWindowsAtTheReach) {
  constexpr double kReach = 0.064;
  const std::deque<Prepared> buf = line(250, 1.0, 10.0);
  const std::size_t i = 125;  // 500 ms
  float full[kFeatureCount], near[kFeatureCount];
  sample_features(buf, i, fovea::protocol::DisplayGeometry{}, full);
  sample_features(buf, i, fovea::protocol::DisplayGeometry{}, near, kReach);
  for (const char* n : {"speed_c_64ms", "disp_64ms", "straight_32ms", "speed_b_256ms", "cos_4ms", "loss_before_s",
                        "speed_b_4ms_lag20ms", "speed_f_4ms_lead12ms"}) {
    EXPECT_EQ(near[at(n)], full[at(n)]) << n;
  }
  // A reach shorter than a step ahead ends it.
  float short_reach[kFeatureCount];
  sample_features(buf, i, fovea::protocol::DisplayGeometry{}, short_reach, 0.012);
  EXPECT_EQ(short_reach[at("speed_f_4ms_lead8ms")], full[at("speed_f_4ms_lead8ms")]);
  EXPECT_TRUE(std::isnan(short_reach[at("speed_f_4ms_lead12ms")]));
  for (const char* n : {"speed_c_256ms", "speed_f_256ms", "speed_c_128ms"}) EXPECT_NEAR(near[at(n)], 10.0, 0.02) << n;
  EXPECT_NEAR(near[at("cos_256ms")], 1.0, 1e-5);
  EXPECT_NEAR(near[at("straight_256ms")], 1.0, 1e-5);
  // [t - 256 ms, t + 64 ms] of a line at 10 deg/s: 3.2 deg long, RMS spread 3.2 / sqrt(12).
  EXPECT_NEAR(near[at("disp_256ms")], 3.2 / std::sqrt(12.0), 0.02);
  EXPECT_FLOAT_EQ(near[at("loss_after_s")], static_cast<float>(kReach));

  // Beyond the reach (and the sample that brackets it): a jump, then a loss. Nothing changes.
  std::deque<Prepared> later = buf;
  for (std::size_t k = i + 18; k < later.size(); ++k) later[k].x += 12;
  for (std::size_t k = i + 30; k < i + 40; ++k) later[k].kind = Prepared::Kind::Blink;
  float changed[kFeatureCount];
  sample_features(later, i, fovea::protocol::DisplayGeometry{}, changed, kReach);
  EXPECT_EQ(0, std::memcmp(near, changed, sizeof near));
  // A loss within the reach ends the scales that reach it, as at the full reach.
  for (std::size_t k = i + 10; k < i + 20; ++k) later[k].kind = Prepared::Kind::Blink;  // 40 ms ahead
  sample_features(later, i, fovea::protocol::DisplayGeometry{}, changed, kReach);
  EXPECT_NEAR(changed[at("loss_after_s")], 0.040, 1e-6);
  EXPECT_TRUE(std::isnan(changed[at("speed_c_64ms")]));
  EXPECT_TRUE(std::isnan(changed[at("speed_c_256ms")]));
  EXPECT_TRUE(std::isfinite(changed[at("speed_c_32ms")]));
}

// Hours of 1000 Hz gaze far from the screen's centre: the sums restart every chunk, so a fixation's
// spread is what it was at the start.
TEST(Features, TheSumsDoNotDriftOverALongStream) {
  FeatureWindow w;
  float first[kFeatureCount], later[kFeatureCount];
  const auto fixation = [](std::size_t k) {  // a fixed, jittered point at 35 deg
    return Prepared{k, static_cast<double>(k) * 0.001, 35 + 0.01 * static_cast<double>((k * 7919) % 13) / 13.0,
                    -20 + 0.01 * static_cast<double>((k * 104729) % 17) / 17.0, Prepared::Kind::Gaze};
  };
  constexpr std::size_t kSamples = 600000;  // 10 minutes
  std::size_t dropped = 0;
  for (std::size_t k = 0; k < kSamples; ++k) {
    w.push(fixation(k));
    if (k == 2000) w.features(1000 - dropped, fovea::protocol::DisplayGeometry{}, first);
    if (k > 1600) {
      w.pop_front(1);
      ++dropped;
    }
  }
  // The same phase of the jitter (both patterns repeat every 13 * 17 samples).
  const std::size_t i = 1000 + 221 * ((kSamples - 2000) / 221);
  w.features(i - dropped, fovea::protocol::DisplayGeometry{}, later);
  for (const char* n : {"disp_4ms", "disp_256ms", "straight_256ms", "noise_deg"}) {
    EXPECT_NEAR(later[at(n)], first[at(n)], 1e-6 * std::abs(static_cast<double>(first[at(n)])) + 1e-9) << n;
  }
}

TEST(Features, GazeOffTheDisplaySaysHowFar) {
  // The default display: 531.3 mm wide at 650 mm, so its edges are atan(265.65 / 650) = 22.23 deg out.
  std::deque<Prepared> buf = line(250, 1.0, 0.0);
  for (auto& p : buf) p.x = 30;
  float f[kFeatureCount];
  sample_features(buf, 100, fovea::protocol::DisplayGeometry{}, f);
  EXPECT_NEAR(f[at("offscreen_deg")], 30 - std::atan(265.65 / 650) * 180 / M_PI, 0.01);
  for (auto& p : buf) p.x = 20;
  sample_features(buf, 100, fovea::protocol::DisplayGeometry{}, f);
  EXPECT_EQ(f[at("offscreen_deg")], 0.0f);
}

TEST(Trees, SmoothingCallsASaccadeByTheShortWindowAndTheRestByTheLongOneNoiseNearALossABlink) {
  std::string features = "features " + std::to_string(kFeatureCount);
  for (const auto& n : feature_names()) features += " " + n;
  const std::string text = replaced(replaced(replaced(kModel, "features 2 a b", features), "classes 2 fixation saccade",
                                             "classes 4 fixation saccade pursuit noise"),
                                    "baseline 0.5 0", "baseline 0 0 0 0");
  const TreesModel m(text, "m.trees");
  const double ones[4] = {1, 1, 1, 1};
  const double sacc_near[4] = {0.3, 0.4, 0.2, 0.1}, wide[4] = {0.3, 0.35, 0.25, 0.1};
  EXPECT_EQ(m.smoothed_label(sacc_near, wide, ones, false), Label::Saccade);
  const double fix_near[4] = {0.5, 0.4, 0.05, 0.05};
  EXPECT_EQ(m.smoothed_label(fix_near, wide, ones, false), Label::Fixation);  // the wide window's saccade does not count
  const double pursuit_wide[4] = {0.3, 0.1, 0.5, 0.1};
  EXPECT_EQ(m.smoothed_label(fix_near, pursuit_wide, ones, false), Label::Pursuit);
  const double noise_wide[4] = {0.2, 0.1, 0.25, 0.45};
  EXPECT_EQ(m.smoothed_label(fix_near, noise_wide, ones, true), Label::Blink);     // near a loss: the coders' noise
  EXPECT_EQ(m.smoothed_label(fix_near, noise_wide, ones, false), Label::Unknown);  // elsewhere no movement
  // Weights tip the long window's choice (0.3 fixation against 0.25 x 1.5 pursuit), not the short
  // window's saccade.
  const double pursuit_weighed[4] = {1, 1, 1.5, 1};
  EXPECT_EQ(m.smoothed_label(fix_near, wide, pursuit_weighed, false), Label::Pursuit);
  EXPECT_EQ(m.smoothed_label(sacc_near, wide, pursuit_weighed, false), Label::Saccade);
  EXPECT_EQ(m.class_of(Label::Pursuit), 2u);
  EXPECT_EQ(m.class_of(Label::Pso), 4u);  // none
  double p[4];
  const std::vector<float> f(kFeatureCount, 0.5f);
  m.probabilities(f.data(), p);
  EXPECT_NEAR(p[0] + p[1] + p[2] + p[3], 1.0, 1e-12);
  EXPECT_NEAR(p[0] / p[2], std::exp(2.0), 1e-9);  // tree 0 adds 2 to fixation (0.5 <= 1), pursuit has no tree
}

// The coders' noise is a blink within kNoiseNearLossS of a loss, as far ahead as the features see:
// the daemon's features reach 64 ms ahead and cap the time to the next loss there, which once read
// as a loss 64 ms ahead for every sample (every noise sample a blink, large saccades too).
TEST(Trees, NoiseIsABlinkOnlyNearALossTheFeaturesSawOrOffTheDisplay) {
  std::vector<float> f(kFeatureCount, 0.0f);
  const auto set = [&](const char* name, double v) { f[feature_index(name)] = static_cast<float>(v); };
  set("offscreen_deg", 0);
  for (const double reach : {0.064, kFeatureReachS}) {
    set("loss_before_s", kFeatureReachS);
    set("loss_after_s", reach);  // the cap: no loss within the reach
    EXPECT_FALSE(TreesModel::noise_is_blink(f.data(), reach)) << reach;
    set("loss_after_s", 0.050);
    EXPECT_TRUE(TreesModel::noise_is_blink(f.data(), reach)) << reach;
    set("loss_after_s", reach);
    set("loss_before_s", 0.099);
    EXPECT_TRUE(TreesModel::noise_is_blink(f.data(), reach)) << reach;
    set("loss_before_s", 0.101);
    EXPECT_FALSE(TreesModel::noise_is_blink(f.data(), reach)) << reach;
    set("offscreen_deg", 0.5);
    EXPECT_TRUE(TreesModel::noise_is_blink(f.data(), reach)) << reach;
    set("offscreen_deg", 0);
  }
  // With the whole reach a loss 64-100 ms ahead is near; 100 ms or more is not.
  f[feature_index("loss_before_s")] = static_cast<float>(kFeatureReachS);
  f[feature_index("loss_after_s")] = 0.080f;
  EXPECT_TRUE(TreesModel::noise_is_blink(f.data(), kFeatureReachS));
  f[feature_index("loss_after_s")] = 0.120f;
  EXPECT_FALSE(TreesModel::noise_is_blink(f.data(), kFeatureReachS));
}

// The whole pipeline with trees that call every gaze sample noise: a blink within 100 ms of a loss
// of data, a short one the front end filled in too (the features' times to a loss see no filled
// gap; short blinks are such gaps), unknown further away. Before, the daemon's features, whose time
// to the next loss stops at their 64 ms reach, made every noise sample a blink.
TEST(Trees, NoiseNearAFilledOrUnfilledLossIsABlinkAndUnknownElsewhere) {
  const std::string noise = "fovea-trees 1\nfeatures " + std::to_string(kFeatureCount);
  std::string text = noise;
  for (const auto& n : feature_names()) text += " " + n;
  text += "\nclasses 2 noise fixation\nbaseline 0 0\ntrees 1\ntree 0 1\n-1 0 0 0 0 1\n";
  const auto model = std::make_shared<const GbtModel>(text, "noise.trees");
  GbtOptions o;
  o.pso = PsoConvention::None;
  auto pipeline = make_trees_pipeline(model, fovea::protocol::DisplayGeometry{}, o);
  // 250 Hz, 3 s of still gaze; lost: 1.000-1.040 s (bridged by the 75 ms fill-in), 2.000-2.300 s.
  std::vector<Labeled> out;
  std::vector<double> t;
  for (int i = 0; i < 750; ++i) {
    Sample s;
    s.t_s = i * 0.004;
    s.valid = !(s.t_s >= 0.9999 && s.t_s < 1.0399) && !(s.t_s >= 1.9999 && s.t_s < 2.2999);
    t.push_back(s.t_s);
    pipeline->push(s, out);
  }
  pipeline->flush(out);
  ASSERT_EQ(out.size(), t.size());
  for (std::size_t i = 0; i < out.size(); ++i) {
    const double d = std::min({std::abs(t[i] - 0.998), std::abs(t[i] - 1.040), std::abs(t[i] - 1.998),
                               std::abs(t[i] - 2.300)});
    const bool lost = t[i] >= 1.9999 && t[i] < 2.2999;
    if (lost) continue;  // the front end's label of an unbridged loss
    if (d < 0.095) {
      EXPECT_EQ(out[i].label, Label::Blink) << t[i];
    } else if (d > 0.105) {
      EXPECT_EQ(out[i].label, Label::Unknown) << t[i];
    }
  }
}

// --- the pursuit-onset hold (trees_core.h, OnsetHold) -------------------------------------------

namespace {

// Labels at 250 Hz from a pattern: F a sure fixation, f a doubtful one, P pursuit, S saccade,
// '|' a new gaze run (the next label's); what leaves the hold, as a pattern.
struct HoldRun {
  OnsetHold hold{0.100, 0.018};  // 100 ms to begin, 18 ms to last (5 samples, not 4)
  std::vector<Labeled> out;
  std::uint64_t next = 0, run = 0;
  void push(const std::string& pattern, bool all = false) {
    for (const char c : pattern) {
      if (c == '|') {
        ++run;
        continue;
      }
      const Label l = c == 'P' ? Label::Pursuit : c == 'S' ? Label::Saccade : Label::Fixation;
      hold.push({{next, l}, static_cast<double>(next) * 0.004, run, c == 'f'});
      ++next;
    }
    hold.release(out, all);
  }
  std::string labels() const {
    std::string s;
    for (std::size_t i = 0; i < out.size(); ++i) {
      EXPECT_EQ(out[i].index, i) << "labels leave in input order";
      s += out[i].label == Label::Pursuit ? 'P' : out[i].label == Label::Saccade ? 'S' : 'F';
    }
    return s;
  }
};

}  // namespace

TEST(OnsetHold, DoubtfulFixationsBeforeALastingPursuitStartItAndNothingElseWaits) {
  HoldRun h;
  h.push("FF");
  EXPECT_EQ(h.labels(), "FF") << "nothing held: a sure label leaves at once";
  h.push("fff");
  EXPECT_EQ(h.labels(), "FF") << "doubtful fixations wait";
  h.push("PPP");
  EXPECT_EQ(h.labels(), "FF") << "a pursuit of 8 ms is not yet one of 18";
  h.push("PPP");
  EXPECT_EQ(h.labels(), "FFPPPPPPPPP") << "confirmed: the doubtful fixations are its start";
  EXPECT_DOUBLE_EQ(h.hold.max_wait_s(), 0.118);
}

TEST(OnsetHold, AnythingButDoubtOrAPursuitTooShortOrTooLateLeavesAFixation) {
  HoldRun sure;  // a sure fixation between
  sure.push("ffFPPPPPPP");
  EXPECT_EQ(sure.labels(), "FFFPPPPPPP");
  HoldRun saccade;
  saccade.push("ffSPPPPPPP");
  EXPECT_EQ(saccade.labels(), "FFSPPPPPPP");
  HoldRun run;  // a loss: the pursuit is another gaze run's
  run.push("ff|PPPPPPP");
  EXPECT_EQ(run.labels(), "FFPPPPPPP");
  HoldRun short_pursuit;  // 8 ms of pursuit, then a sure fixation
  short_pursuit.push("ffPPFFF");
  EXPECT_EQ(short_pursuit.labels(), "FFPPFFF");
  HoldRun flicker;  // a short pursuit, doubt again, then a lasting pursuit: all of it the pursuit's
  flicker.push("ffPPffPPPPPP");
  EXPECT_EQ(flicker.labels(), "PPPPPPPPPPPP");
  // 30 doubtful fixations (120 ms) before the pursuit: only those within 100 ms of it start it.
  HoldRun late;
  late.push(std::string(30, 'f') + "PPPPPPP");
  EXPECT_EQ(late.labels(), std::string(5, 'F') + std::string(25, 'P') + "PPPPPPP");
  // The stream ends undecided: fixations.
  HoldRun end;
  end.push("fffPP");
  EXPECT_EQ(end.labels(), "");
  end.push("", true);
  EXPECT_EQ(end.labels(), "FFFPP");
}

// --- the two-stage bundle (trees_core.h, GbtModel) ----------------------------------------------

namespace {

std::string ensemble(const std::vector<std::string>& features, const std::string& classes) {
  std::string s = "fovea-trees 1\nfeatures " + std::to_string(features.size());
  for (const auto& n : features) s += " " + n;
  return s + "\nclasses 2 " + classes + "\nbaseline 0 0\ntrees 1\ntree 0 1\n-1 0 0 0 0 1\n";
}

const std::vector<std::string> kClasses = {"fixation", "saccade"};

std::string bundle() {
  const auto ctx = context_feature_names(kClasses);
  return "# two stages\nfovea-gbt 1\nstage frame\n" + ensemble(feature_names(), "fixation saccade") +
         "stage online 0.032\n" + ensemble(ctx, "fixation pursuit") + "stage offline 0.512\n" +
         ensemble(ctx, "fixation saccade");
}

// bundle() with the online chain's own first stage, over features reaching `reach` ahead.
std::string bundle_with_frame_online(const std::string& reach = "0.064",
                                     const std::string& classes = "fixation saccade") {
  return replaced(bundle(), "stage online 0.032\n",
                  "stage frame-online " + reach + "\n" + ensemble(feature_names(), classes) + "stage online 0.032\n");
}

std::string model_error(const std::string& text) {
  return error_of([&] { GbtModel(text, "m.gbt"); });
}

}  // namespace

TEST(GbtModel, ABundleHoldsTheFirstStageAndBothSecondStages) {
  const GbtModel m(bundle(), "m.gbt");
  EXPECT_EQ(m.frame().trees().class_names(), kClasses);
  ASSERT_NE(m.context(false), nullptr);
  ASSERT_NE(m.context(true), nullptr);
  EXPECT_EQ(m.context(false)->trees().class_names()[1], "pursuit");
  EXPECT_DOUBLE_EQ(m.lookahead_s(false), 0.032);
  EXPECT_DOUBLE_EQ(m.lookahead_s(true), 0.512);
  const GbtModel frame_only(ensemble(feature_names(), "fixation saccade"), "m.trees");  // the older format
  EXPECT_EQ(frame_only.context(false), nullptr);
  EXPECT_EQ(frame_only.context(true), nullptr);
  const GbtModel offline_only(replaced(bundle(), "stage online 0.032\n" + ensemble(context_feature_names(kClasses), "fixation pursuit"), ""), "m");
  EXPECT_EQ(offline_only.context(false), nullptr);
  EXPECT_NE(offline_only.context(true), nullptr);
}

// The daemon's chain may have a first stage of its own over features that reach less far ahead, so
// that its labels are final sooner (latency: that reach + the second stage's look-ahead + the
// smoothing); the offline chain keeps the whole reach.
TEST(GbtModel, TheOnlineChainMayHaveItsOwnFirstStageWithAShorterReach) {
  const auto m = std::make_shared<const GbtModel>(bundle_with_frame_online(), "m.gbt");
  EXPECT_NE(&m->frame(false), &m->frame(true));
  EXPECT_DOUBLE_EQ(m->reach_s(false), 0.064);
  EXPECT_DOUBLE_EQ(m->reach_s(true), kFeatureReachS);
  const GbtModel plain(bundle(), "m.gbt");
  EXPECT_EQ(&plain.frame(false), &plain.frame(true));
  EXPECT_DOUBLE_EQ(plain.reach_s(false), kFeatureReachS);
  // The trees' own latency (trees_only: without the smoothing and ivvt's core beside them).
  GbtOptions o;
  o.trees_only = true;
  const double front = make_trees_pipeline(nullptr, fovea::protocol::DisplayGeometry{}, o)->latency_s() - kFeatureReachS;
  const auto trees_latency = [&] {
    return make_trees_pipeline(m, fovea::protocol::DisplayGeometry{}, o)->latency_s() - front;
  };
  EXPECT_NEAR(trees_latency(), 0.064 + 0.032 + kContextSlackS, 1e-12);  // the context waits out its slack
  o.offline = true;
  EXPECT_NEAR(trees_latency(), kFeatureReachS + 0.512 + kContextSlackS, 1e-12);

  EXPECT_EQ(model_error(bundle_with_frame_online("0.3")),
            "m.gbt:11: 'stage frame-online' needs one reach ahead in seconds, in (0, 0.256000]");
  EXPECT_EQ(model_error(bundle_with_frame_online("0")),
            "m.gbt:11: 'stage frame-online' needs one reach ahead in seconds, in (0, 0.256000]");
  EXPECT_EQ(model_error(bundle_with_frame_online("0.064", "fixation pursuit")),
            "m.gbt:11: 'stage frame-online' has other classes than 'stage frame'");
  const std::string after_online =
      bundle() + "stage frame-online 0.064\n" + ensemble(feature_names(), "fixation saccade");
  EXPECT_EQ(model_error(after_online), "m.gbt:27: 'stage frame-online' after 'stage online' (whose features it gives)");
}

// A chain's class weights (trees_core.h): given after its second stage's look-ahead, one per class;
// all 1 where the file gives none or the chain has no second stage.
TEST(GbtModel, AChainsWeightsAreItsSecondStagesOnePerClass) {
  const GbtModel weighed(replaced(bundle(), "stage online 0.032\n", "stage online 0.032 weights 1 1.75\n"), "m.gbt");
  EXPECT_EQ(weighed.weights(false), (std::vector<double>{1, 1.75}));
  EXPECT_EQ(weighed.weights(true), (std::vector<double>{1, 1}));
  const GbtModel frame_only(ensemble(feature_names(), "fixation saccade"), "m.trees");
  EXPECT_EQ(frame_only.weights(false), (std::vector<double>{1, 1}));

  EXPECT_EQ(model_error(replaced(bundle(), "stage online 0.032", "stage online 0.032 weights 1")),
            "m.gbt:11: 'stage online' has 1 weights for its 2 classes");
  EXPECT_EQ(model_error(replaced(bundle(), "stage online 0.032", "stage online 0.032 weights")),
            "m.gbt:11: 'stage online' has 0 weights for its 2 classes");
  EXPECT_EQ(model_error(replaced(bundle(), "stage offline 0.512", "stage offline 0.512 weights 1 0")),
            "m.gbt:19: 'stage offline': weight '0' is not a positive number");
  EXPECT_EQ(model_error(replaced(bundle(), "stage offline 0.512", "stage offline 0.512 weights 1 inf")),
            "m.gbt:19: 'stage offline': weight 'inf' is not a positive number");
  EXPECT_EQ(model_error(replaced(bundle(), "stage offline 0.512", "stage offline 0.512 weights 1 2x")),
            "m.gbt:19: 'stage offline': weight '2x' is not a positive number");
  EXPECT_EQ(model_error(replaced(bundle(), "stage online 0.032", "stage online 0.032 1 2")),
            "m.gbt:11: 'stage online' takes a look-ahead and then only 'weights' and 'hold', not '1'");
  EXPECT_EQ(model_error(replaced(bundle(), "stage online 0.032", "stage online weights 1 2")),
            "m.gbt:11: 'stage online' needs one look-ahead in seconds, in (0, 0.512000]");
}

// A chain's pursuit-onset hold (trees_core.h, OnsetHold): after the look-ahead, before or after the
// weights; none where the file gives none.
TEST(GbtModel, AChainsHoldFollowsItsLookAheadWithThreeNumbers) {
  const GbtModel held(replaced(bundle(), "stage online 0.032\n", "stage online 0.032 hold 0.192 0.3 0.05\n"), "m.gbt");
  EXPECT_EQ(held.hold(false), (PursuitHold{0.192, 0.3, 0.05}));
  EXPECT_EQ(held.hold(true).hold_s, 0.0);
  EXPECT_EQ(held.weights(false), (std::vector<double>{1, 1}));
  const GbtModel both(replaced(bundle(), "stage online 0.032\n", "stage online 0.032 weights 1 2 hold 0.1 0.5 0\n"),
                      "m.gbt");
  EXPECT_EQ(both.weights(false), (std::vector<double>{1, 2}));
  EXPECT_EQ(both.hold(false), (PursuitHold{0.1, 0.5, 0}));
  const GbtModel first(replaced(bundle(), "stage online 0.032\n", "stage online 0.032 hold 0.1 0.5 0 weights 1 2\n"),
                       "m.gbt");
  EXPECT_EQ(first.weights(false), (std::vector<double>{1, 2}));
  EXPECT_EQ(first.hold(false), (PursuitHold{0.1, 0.5, 0}));

  EXPECT_EQ(model_error(replaced(bundle(), "stage online 0.032", "stage online 0.032 hold 0.1 0.5")),
            "m.gbt:11: 'stage online': 'hold' takes three numbers: HOLD_S RATIO MIN_S");
  EXPECT_EQ(model_error(replaced(bundle(), "stage online 0.032", "stage online 0.032 hold 0.1 x 0")),
            "m.gbt:11: 'stage online': 'hold' takes three numbers: HOLD_S RATIO MIN_S, not 'x'");
  EXPECT_EQ(model_error(replaced(bundle(), "stage online 0.032", "stage online 0.032 hold 0.1 1.5 0")),
            "m.gbt:11: 'stage online': a pursuit hold's ratio 1.500000 is not in (0, 1]");
  EXPECT_EQ(model_error(replaced(bundle(), "stage online 0.032", "stage online 0.032 hold 0 0.5 0")),
            "m.gbt:11: 'stage online': a hold of 0 s");
  EXPECT_EQ(model_error(replaced(bundle(), "stage offline 0.512", "stage offline 0.512 hold 2 0.5 0")),
            "m.gbt:19: 'stage offline': a pursuit hold of 2.000000 s is not in [0, 1] s");
  EXPECT_EQ(model_error(replaced(bundle(), "stage online 0.032", "stage online 0.032 hold 0.1 0.5 0 hold 0.1 0.5 0")),
            "m.gbt:11: 'stage online' has a second 'hold'");
  EXPECT_EQ(model_error(replaced(bundle(), "stage online 0.032", "stage online 0.032 weights 1 1 weights 1 1")),
            "m.gbt:11: 'stage online' has a second 'weights'");
}

TEST(GbtModel, ADamagedBundleIsRefusedWithFileAndLine) {
  EXPECT_EQ(model_error(replaced(bundle(), "fovea-gbt 1", "fovea-gbt 2")), "m.gbt:2: format version is not 1");
  EXPECT_EQ(model_error(replaced(bundle(), "fovea-gbt 1", "fovea-gbz 1")),
            "m.gbt:2: expected 'fovea-gbt' or 'fovea-trees', found 'fovea-gbz'");
  EXPECT_EQ(model_error(replaced(bundle(), "stage frame", "stage frames")),
            "m.gbt:3: stage 'frames' is none of frame, frame-online, online, offline");
  EXPECT_EQ(model_error(replaced(bundle(), "stage online 0.032", "stage online 0.6")),
            "m.gbt:11: 'stage online' needs one look-ahead in seconds, in (0, 0.512000]");
  EXPECT_EQ(model_error(replaced(bundle(), "stage online 0.032", "stage online")),
            "m.gbt:11: 'stage online' needs one look-ahead in seconds, in (0, 0.512000]");
  EXPECT_EQ(model_error(replaced(bundle(), "stage offline 0.512", "stage online 0.5")), "m.gbt:19: a second 'stage online'");
  EXPECT_EQ(model_error(replaced(bundle(), "stage frame\n", "frame\n")), "m.gbt:3: expected 'stage', found 'frame'");
  // A second stage must read the context of the first's classes: here it names other features.
  const std::string other = replaced(bundle(), "stage frame\n" + ensemble(feature_names(), "fixation saccade"),
                                     "stage frame\n" + ensemble(feature_names(), "fixation pursuit"));
  EXPECT_NE(model_error(other).find("m.gbt:13: the model reads feature '"), std::string::npos);
  // The ensembles' own errors carry the file's line numbers.
  EXPECT_EQ(model_error(replaced(bundle(), "tree 0 1\n-1 0 0 0 0 1\nstage online", "tree 0 1\n-1 0 0 0 0 nan\nstage online")),
            "m.gbt:10: node value 'nan' is not a finite number");
  EXPECT_EQ(model_error("fovea-gbt 1\n"), "m.gbt:1: no 'stage frame'");
  EXPECT_EQ(model_error(""), "m.gbt:1: expected 'fovea-gbt' or 'fovea-trees', found ''");
}
