// SPDX-License-Identifier: Apache-2.0
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

void stampe_filter(std::vector<Sample>& samples) {
  // Each decision reads the input, not what the filter already changed (a three-sample window
  // sliding over the raw signal, as the tracker's stage does with its delay of one sample).
  const std::vector<Sample> in = samples;
  const auto usable = [&in](std::size_t i) { return in[i].valid && std::isfinite(in[i].x_deg) && std::isfinite(in[i].y_deg); };
  const auto despike = [](double a, double b, double c) {
    if ((b > a && b > c) || (b < a && b < c)) return std::abs(b - a) < std::abs(b - c) ? a : c;
    return b;
  };
  for (std::size_t i = 1; i + 1 < in.size(); ++i) {
    if (!usable(i - 1) || !usable(i) || !usable(i + 1)) continue;
    samples[i].x_deg = despike(in[i - 1].x_deg, in[i].x_deg, in[i + 1].x_deg);
    samples[i].y_deg = despike(in[i - 1].y_deg, in[i].y_deg, in[i + 1].y_deg);
  }
}

void degrade(std::vector<Sample>& samples, const Degradation& d) {
  if (d.heuristic_filter) {
    Degradation noise_only = d;
    noise_only.heuristic_filter = false;
    noise_only.dropouts_per_s = 0;
    degrade(samples, noise_only);
    stampe_filter(samples);
    Degradation drops_only = d;
    drops_only.heuristic_filter = false;
    drops_only.extra_noise_deg = 0;
    drops_only.seed = d.seed + 1;  // independent of the noise draws
    degrade(samples, drops_only);
    return;
  }
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

namespace {

// Runs of one class: [first, end) sample indices.
std::vector<std::pair<std::size_t, std::size_t>> runs_of(const std::vector<Label>& labels, Label c) {
  std::vector<std::pair<std::size_t, std::size_t>> runs;
  for (std::size_t i = 0; i < labels.size();) {
    if (labels[i] != c) {
      ++i;
      continue;
    }
    std::size_t j = i;
    while (j < labels.size() && labels[j] == c) ++j;
    runs.emplace_back(i, j);
    i = j;
  }
  return runs;
}

}  // namespace

double event_f1(const std::vector<Label>& truth, const std::vector<Label>& predicted, Label c, double min_iou) {
  if (truth.size() != predicted.size()) throw std::invalid_argument("event_f1: sequences differ in length");
  const auto true_events = runs_of(truth, c), found = runs_of(predicted, c);
  std::size_t hits = 0, j = 0;
  std::vector<bool> used(found.size(), false);
  for (const auto& [ts, te] : true_events) {
    while (j < found.size() && found[j].second <= ts) ++j;
    for (std::size_t k = j; k < found.size() && found[k].first < te; ++k) {
      const auto [fs, fe] = found[k];
      const double inter = static_cast<double>(std::min(te, fe) - std::max(ts, fs));
      const double uni = static_cast<double>(std::max(te, fe) - std::min(ts, fs));
      if (!used[k] && inter / uni >= min_iou) {
        used[k] = true;
        ++hits;
        break;
      }
    }
  }
  const std::size_t misses = true_events.size() - hits, false_events = found.size() - hits;
  if (hits + misses + false_events == 0) return std::numeric_limits<double>::quiet_NaN();
  return 2.0 * static_cast<double>(hits) / static_cast<double>(2 * hits + misses + false_events);
}

ProvisionalLatency provisional_latency(const std::vector<Label>& truth, const std::vector<Sample>& samples,
                                       const std::vector<ProvisionalEvent>& events) {
  if (truth.size() != samples.size()) throw std::invalid_argument("provisional_latency: sequences differ in length");
  constexpr double kBefore = 0.020, kAfter = 0.050;
  ProvisionalLatency r;
  std::vector<bool> used(events.size(), false);
  for (const auto& [a, b] : runs_of(truth, Label::Saccade)) {
    const double t0 = samples[a].t_s, t1 = samples[b - 1].t_s;
    bool found = false;
    for (std::size_t k = 0; k < events.size() && !found; ++k) {
      const ProvisionalEvent& e = events[k];
      if (used[k] || e.kind != Label::Saccade || e.phase != Phase::Start || e.t_s < t0 - kBefore || e.t_s > t1) continue;
      used[k] = found = true;
      r.saccade.latency_s.push_back(e.emitted_s - t0);
    }
    if (!found) ++r.saccade.missed;
    // The landing is the saccade's end, also where a PSO follows it before the fixation (as
    // eval_classify_human.py scores the human coder's landings).
    std::size_t f = b;
    while (f < truth.size() && truth[f] == Label::Pso) ++f;
    if (f >= truth.size() || truth[f] != Label::Fixation) continue;
    const double tf = samples[b].t_s;
    found = false;
    for (const ProvisionalEvent& e : events) {
      if (e.kind != Label::Fixation || e.t_s < tf - kBefore || e.t_s > tf + kAfter) continue;
      found = true;
      r.fixation.latency_s.push_back(e.emitted_s - tf);
      break;
    }
    if (!found) ++r.fixation.missed;
  }
  for (std::size_t k = 0; k < events.size(); ++k) {
    if (!used[k] && events[k].kind == Label::Saccade && events[k].phase == Phase::Start) ++r.false_starts;
  }
  return r;
}

ProvisionalAgreement provisional_agreement(const std::vector<ProvisionalEvent>& events, const std::vector<Label>& final_labels,
                                           const std::vector<Sample>& samples) {
  if (final_labels.size() != samples.size()) throw std::invalid_argument("provisional_agreement: sequences differ in length");
  ProvisionalCheck check;
  for (const ProvisionalEvent& e : events) check.provisional(e);
  // The final events as the daemon's stage makes them: runs of one class (PSO with its saccade).
  const auto merged = [](Label l) { return l == Label::Pso ? Label::Saccade : l; };
  for (std::size_t i = 1; i < final_labels.size(); ++i) {
    const Label before = merged(final_labels[i - 1]), now = merged(final_labels[i]);
    if (before == now) continue;
    check.final_event(before, Phase::End, samples[i].t_s);
    check.final_event(now, Phase::Start, samples[i].t_s);
  }
  std::vector<ProvisionalEvent> retracted;
  check.final_upto(std::numeric_limits<double>::infinity(), retracted);
  return {check.emitted(), check.confirmed(), check.retracted()};
}

}  // namespace fovea::trackerd::classify
