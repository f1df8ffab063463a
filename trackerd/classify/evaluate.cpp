#include "classify/evaluate.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace fovea::trackerd::classify {

OnsetLatency onset_latency(const std::vector<Label>& truth, const std::vector<Label>& predicted,
                           const std::vector<double>& final_t_s, const std::vector<Sample>& samples, Label c) {
  if (truth.size() != predicted.size() || truth.size() != final_t_s.size() || truth.size() != samples.size()) {
    throw std::invalid_argument("onset_latency: sequences differ in length");
  }
  OnsetLatency out;
  const std::size_t n = truth.size();
  for (std::size_t a = 0; a < n;) {
    if (truth[a] != c) {
      ++a;
      continue;
    }
    std::size_t b = a;
    while (b < n && truth[b] == c) ++b;
    // The predicted run overlapping [a, b): its first sample, walking back from the first overlap.
    std::size_t k = a;
    while (k < b && predicted[k] != c) ++k;
    if (k == b) {
      ++out.missed;
    } else {
      while (k > 0 && predicted[k - 1] == c) --k;
      const double latency = final_t_s[k] - samples[a].t_s;
      if (std::isfinite(latency)) out.latency_s.push_back(latency);
    }
    a = b;
  }
  return out;
}

double quantile(std::vector<double> v, double q) {
  if (v.empty()) return std::numeric_limits<double>::quiet_NaN();
  std::sort(v.begin(), v.end());
  const auto k = static_cast<std::size_t>(std::lround(q * static_cast<double>(v.size() - 1)));
  return v[k];
}

double class_kappa(const std::vector<Label>& truth, const std::vector<Label>& predicted, Label c) {
  if (truth.size() != predicted.size()) throw std::invalid_argument("class_kappa: sequences differ in length");
  double both = 0, t_only = 0, p_only = 0, neither = 0;
  for (std::size_t i = 0; i < truth.size(); ++i) {
    const bool t = truth[i] == c, p = predicted[i] == c;
    (t && p ? both : t ? t_only : p ? p_only : neither) += 1;
  }
  const double n = both + t_only + p_only + neither;
  if (n == 0) return std::numeric_limits<double>::quiet_NaN();
  const double po = (both + neither) / n;
  const double pt = (both + t_only) / n, pp = (both + p_only) / n;
  const double pe = pt * pp + (1 - pt) * (1 - pp);
  if (pe >= 1) return std::numeric_limits<double>::quiet_NaN();
  return (po - pe) / (1 - pe);
}

double overall_kappa(const std::vector<Label>& truth, const std::vector<Label>& predicted) {
  if (truth.size() != predicted.size()) throw std::invalid_argument("overall_kappa: sequences differ in length");
  std::array<double, kLabelCount> tc{}, pc{};
  double agree = 0;
  for (std::size_t i = 0; i < truth.size(); ++i) {
    tc[static_cast<std::size_t>(truth[i])] += 1;
    pc[static_cast<std::size_t>(predicted[i])] += 1;
    if (truth[i] == predicted[i]) agree += 1;
  }
  const double n = static_cast<double>(truth.size());
  if (n == 0) return std::numeric_limits<double>::quiet_NaN();
  double pe = 0;
  for (std::size_t k = 0; k < tc.size(); ++k) pe += (tc[k] / n) * (pc[k] / n);
  if (pe >= 1) return std::numeric_limits<double>::quiet_NaN();
  return (agree / n - pe) / (1 - pe);
}

void degrade(std::vector<Sample>& samples, const Degradation& d) {
  std::mt19937_64 rng(d.seed);
  std::normal_distribution<double> gauss(0.0, 1.0);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  std::exponential_distribution<double> gap_len(1.0 / d.dropout_mean_s);
  double drop_until = -std::numeric_limits<double>::infinity();
  double prev_t = samples.empty() ? 0 : samples.front().t_s;
  for (Sample& s : samples) {
    if (d.extra_noise_deg > 0) {
      s.x_deg += d.extra_noise_deg * gauss(rng);
      s.y_deg += d.extra_noise_deg * gauss(rng);
    }
    if (d.dropouts_per_s > 0) {
      const double dt = std::max(0.0, s.t_s - prev_t);
      if (s.t_s >= drop_until && uniform(rng) < 1 - std::exp(-d.dropouts_per_s * dt)) {
        drop_until = s.t_s + std::min(gap_len(rng), 10 * d.dropout_mean_s);
      }
      if (s.t_s < drop_until) {
        s.valid = false;
        s.x_deg = s.y_deg = std::numeric_limits<double>::quiet_NaN();
      }
    }
    prev_t = s.t_s;
  }
}

}  // namespace fovea::trackerd::classify
