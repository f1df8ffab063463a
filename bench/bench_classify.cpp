// SPDX-License-Identifier: Apache-2.0
// Accuracy and cost of every eye-movement classifier on labelled synthetic gaze (the generator
// knows the true movement of every sample), degraded the way real trackers degrade: sample rate
// (60 Hz remote ... 1000 Hz lab tracker), added gaussian noise, random runs of lost samples, the
// movements the plain generator leaves out (microsaccades, catch-up saccades) and the tracker's own
// heuristic filter (Stampe 1993), which colours the noise.
// Prints one markdown table: sample-level Cohen's kappa per class (one class vs the rest) and over
// all labels, the share of samples labelled pso/unknown, and the cost per sample; then how long
// after a true fixation or saccade onset the online classifier's final label said so (two tables),
// and the provisional events' latency, misses and retractions (three tables).
//
// Then which of the realistic generator's small saccades each method finds: catch-up saccades
// within pursuit and microsaccades within fixation (issue 43: "a saccade detector that does not
// lose saccades within pursuit").
//
//   bench_classify [--seconds S] [--seeds N] [--methods A,B] [--accuracy-only | --small-saccades]
//     defaults: 120 s of gaze per seed, 3 seeds, every method, every table. --methods keeps the main
//     table and the small saccades' to those methods (gbt+pso=none: gbt without a PSO class,
//     gbt+pso=onset: with its PSO from the oscillation's onset, gbt+pursuit-weight=W: with that
//     weight instead of its model's, gbt+pursuit-hold=MS: with that pursuit-onset hold, 0 none,
//     beside them); --accuracy-only prints the main table and the cost summary alone,
//     --small-saccades the small saccades' table alone.
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <optional>
#include <string>
#include <vector>

#include "classify/classifier.h"
#include "classify/evaluate.h"
#include "sim/synthetic_labelled.h"
#include "sim/synthetic_gaze.h"

using namespace fovea;
using namespace fovea::trackerd;
using namespace fovea::trackerd::classify;

namespace {

using Labelled = LabelledGaze;

struct Condition {
  const char* name;
  Degradation d;
  bool realistic = false;  // realistic_gaze_options(): microsaccades, catch-up saccades, PSO, blink movements
  double noise_deg = 0.03;  // the generator's tracker noise (standard deviation per axis) ...
  double noise_alpha = 0;   // ... and its spectral slope
};

Labelled synthetic(double rate_hz, double seconds, std::uint64_t seed, const Condition& c) {
  SyntheticGazeOptions o;
  if (c.realistic) o = realistic_gaze_options(rate_hz, seed);
  o.rate_hz = rate_hz;
  o.seed = seed;
  o.noise_deg = c.noise_deg;
  o.noise_alpha = c.noise_alpha;
  return synthetic_labelled(o, seconds);
}

// The condition's seeds of synthetic gaze, degraded as it says (seed s: generator s + 1, degradation
// 100 + s), the same data for every method that is scored on it.
std::vector<Labelled> degraded(double rate_hz, const Condition& c, double seconds, int seeds) {
  std::vector<Labelled> data;
  for (int s = 0; s < seeds; ++s) {
    Labelled l = synthetic(rate_hz, seconds, static_cast<std::uint64_t>(s + 1), c);
    Degradation d = c.d;
    d.seed = static_cast<std::uint64_t>(100 + s);
    degrade(l.samples, d);
    data.push_back(std::move(l));
  }
  return data;
}

std::string fmt(double k) {
  if (std::isnan(k)) return "  -  ";
  char b[16];
  std::snprintf(b, sizeof b, "%.3f", k);
  return b;
}

// Event latency of the final labels (issue 25, goal 4): the true onset of each fixation and saccade
// to the moment the online classifier's label for that event's first sample became final (pushing
// one sample at a time, as the daemon does). The latency a client sees adds the daemon's and the
// network's (bench_latency).
void print_onset_latency(const double* rates, const Condition& c, double seconds, int seeds) {
  std::printf("\nOnset latency of final labels, condition %s: p50 / p99 ms from the true onset to the final label "
              "of the detected event's first sample; missed = true events no detected event of the class "
              "overlaps.\n\n",
              c.name);
  std::printf("| rate Hz | method | fixation onset p50 | p99 | missed %% | saccade onset p50 | p99 | missed %% |\n");
  std::printf("|---:|---|---:|---:|---:|---:|---:|---:|\n");
  for (int r = 0; r < 4; ++r) {
    for (const ClassifierInfo& m : classifiers()) {
      if (m.name == "lee2009") continue;  // no latency: it labels each sample on arrival
      OnsetLatency fix, sac;
      for (int s = 0; s < seeds; ++s) {
        Labelled l = synthetic(rates[r], seconds, static_cast<std::uint64_t>(s + 1), c);
        Degradation d = c.d;
        d.seed = static_cast<std::uint64_t>(100 + s);
        degrade(l.samples, d);
        ClassifierOptions o;
        o.nominal_rate_hz = rates[r];
        const OnlineLabels p = classify_online(m.name, o, l.samples);
        for (auto [cls, acc] : {std::pair{Label::Fixation, &fix}, std::pair{Label::Saccade, &sac}}) {
          const OnsetLatency one = onset_latency(l.truth, p.labels, p.final_t_s, l.samples, cls);
          acc->latency_s.insert(acc->latency_s.end(), one.latency_s.begin(), one.latency_s.end());
          acc->missed += one.missed;
        }
      }
      const auto missed = [](const OnsetLatency& o) {
        return 100.0 * static_cast<double>(o.missed) / static_cast<double>(o.missed + o.latency_s.size());
      };
      std::printf("| %.0f | %s | %.0f | %.0f | %.1f | %.0f | %.0f | %.1f |\n", rates[r], m.name.c_str(),
                  1000 * quantile(fix.latency_s, 0.5), 1000 * quantile(fix.latency_s, 0.99), missed(fix),
                  1000 * quantile(sac.latency_s, 0.5), 1000 * quantile(sac.latency_s, 0.99), missed(sac));
    }
  }
}

// Event-level F1 (IoU >= 0.5, Startsev et al. 2019) per class, as eval_classify_human.py reports on
// the human-coded data. A saccade's event includes its PSO, in the truth and in a method's labels.
void print_event_f1(const double* rates, const std::vector<const Condition*>& conditions, double seconds, int seeds) {
  std::printf("\nEvent-level F1 (a true and a found event of the class match when their intersection over union is "
              ">= 0.5, each used once; Startsev, Agtzidis & Dorr 2019); pso counted as saccade, in the truth and the "
              "labels.\n\n");
  std::printf("| rate Hz | condition | method | F1 fixation | F1 saccade | F1 pursuit | F1 blink |\n");
  std::printf("|---:|---|---|---:|---:|---:|---:|\n");
  for (int r = 0; r < 4; ++r) {
    for (const Condition* c : conditions) {
      for (const ClassifierInfo& m : classifiers()) {
        if (m.name == "lee2009") continue;
        std::array<double, 4> sum{};
        std::array<int, 4> n{};
        for (int s = 0; s < seeds; ++s) {
          Labelled l = synthetic(rates[r], seconds, static_cast<std::uint64_t>(s + 1), *c);
          Degradation d = c->d;
          d.seed = static_cast<std::uint64_t>(100 + s);
          degrade(l.samples, d);
          std::vector<Label> p = classify_all(m.name, rates[r], l.samples);
          for (Label& x : p) x = x == Label::Pso ? Label::Saccade : x;
          for (Label& x : l.truth) x = x == Label::Pso ? Label::Saccade : x;
          int k = 0;
          for (const Label cls : {Label::Fixation, Label::Saccade, Label::Pursuit, Label::Blink}) {
            const double f = event_f1(l.truth, p, cls);
            if (!std::isnan(f)) sum[static_cast<std::size_t>(k)] += f, ++n[static_cast<std::size_t>(k)];
            ++k;
          }
        }
        const auto mean = [&](std::size_t k) { return n[k] ? sum[k] / n[k] : std::nan(""); };
        std::printf("| %.0f | %s | %s | %s | %s | %s | %s |\n", rates[r], c->name, m.name.c_str(), fmt(mean(0)).c_str(),
                    fmt(mean(1)).c_str(), fmt(mean(2)).c_str(), fmt(mean(3)).c_str());
      }
    }
  }
}

// Provisional events (issue 25, goal 2): true onset -> the provisional event, in sample time (the
// newest sample when it was known), and how often the default method's final labels retracted one.
void print_provisional(const double* rates, const Condition& c, double seconds, int seeds) {
  std::printf("\nProvisional events, condition %s: p50 / p99 ms from the true onset to the sample that made the "
              "provisional event known; missed = true events with none; false starts per minute; retracted = "
              "provisional events the default method's (%s) final labels did not confirm within 50 ms.\n\n",
              c.name, classifiers().front().name.c_str());
  std::printf("| rate Hz | saccade onset p50 | p99 | missed %% | fixation onset p50 | p99 | missed %% | false starts /min | "
              "retracted %% |\n");
  std::printf("|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
  for (int r = 0; r < 4; ++r) {
    ProvisionalLatency all;
    ProvisionalAgreement agree;
    for (int s = 0; s < seeds; ++s) {
      Labelled l = synthetic(rates[r], seconds, static_cast<std::uint64_t>(s + 1), c);
      Degradation d = c.d;
      d.seed = static_cast<std::uint64_t>(100 + s);
      degrade(l.samples, d);
      const std::vector<ProvisionalEvent> events = provisional_events(l.samples);
      const ProvisionalLatency one = provisional_latency(l.truth, l.samples, events);
      for (auto [from, to] : {std::pair{&one.saccade, &all.saccade}, std::pair{&one.fixation, &all.fixation}}) {
        to->latency_s.insert(to->latency_s.end(), from->latency_s.begin(), from->latency_s.end());
        to->missed += from->missed;
      }
      all.false_starts += one.false_starts;
      ClassifierOptions o;
      o.nominal_rate_hz = rates[r];
      const ProvisionalAgreement a = provisional_agreement(events, classify_all(classifiers().front().name, o, l.samples), l.samples);
      agree.emitted += a.emitted;
      agree.retracted += a.retracted;
    }
    const auto missed = [](const OnsetLatency& o) {
      return 100.0 * static_cast<double>(o.missed) / static_cast<double>(o.missed + o.latency_s.size());
    };
    std::printf("| %.0f | %.1f | %.1f | %.1f | %.1f | %.1f | %.1f | %.2f | %.1f |\n", rates[r],
                1000 * quantile(all.saccade.latency_s, 0.5), 1000 * quantile(all.saccade.latency_s, 0.99), missed(all.saccade),
                1000 * quantile(all.fixation.latency_s, 0.5), 1000 * quantile(all.fixation.latency_s, 0.99),
                missed(all.fixation), static_cast<double>(all.false_starts) / (seconds * seeds / 60.0),
                100.0 * static_cast<double>(agree.retracted) / static_cast<double>(std::max<std::uint64_t>(1, agree.emitted)));
  }
}

// A method of the main table: a registered one, gbt without a PSO class ("gbt+pso=none") or with
// its PSO from the onset ("gbt+pso=onset"), gbt with another pursuit weight than its model's
// ("gbt+pursuit-weight=W") or another pursuit-onset hold ("gbt+pursuit-hold=MS", ratio 0.3 and
// 20 ms as fovea-ctl's defaults; 0: none).
struct Method {
  std::string name;     // as printed
  std::string method;   // the registry's name
  PsoConvention pso = PsoConvention::Separate;
  double pursuit_weight = 0;  // 0: the model's
  std::optional<PursuitHold> pursuit_hold{};  // unset: the model's
  ClassifierOptions options(double rate_hz) const {
    ClassifierOptions o;
    o.nominal_rate_hz = rate_hz;
    o.pso = pso;
    o.pursuit_weight = pursuit_weight;
    o.pursuit_hold = pursuit_hold;
    return o;
  }
};

// The methods named in a comma-separated list, in classifiers() order (gbt+pso=onset, gbt+pso=none,
// gbt+pursuit-weight=W and gbt+pursuit-hold=MS after gbt); every registered one for "".
std::vector<Method> chosen_methods(const std::string& list) {
  std::vector<std::string> items;
  for (std::size_t at = 0; at <= list.size();) {
    const std::size_t end = std::min(list.find(',', at), list.size());
    items.push_back(list.substr(at, end - at));
    at = end + 1;
  }
  const auto named = [&](const std::string& n) { return std::find(items.begin(), items.end(), n) != items.end(); };
  const std::string weighed = "gbt+pursuit-weight=", held = "gbt+pursuit-hold=";
  std::vector<Method> out;
  for (const ClassifierInfo& m : classifiers()) {
    if (list.empty() || named(m.name)) out.push_back({m.name, m.name});
    if (m.name != "gbt") continue;
    if (named("gbt+pso=onset")) out.push_back({"gbt+pso=onset", "gbt", PsoConvention::Onset});
    if (named("gbt+pso=none")) out.push_back({"gbt+pso=none", "gbt", PsoConvention::None});
    for (const std::string& item : items) {
      const bool is_weight = item.rfind(weighed, 0) == 0;
      if (!is_weight && item.rfind(held, 0) != 0) continue;
      char* end = nullptr;
      const double v = std::strtod(item.c_str() + (is_weight ? weighed : held).size(), &end);
      if (*end != '\0' || !std::isfinite(v) || (is_weight ? !(v > 0) : !(v >= 0 && v <= 1000))) {
        std::fprintf(stderr, "bench_classify: --methods: %s: %s\n", item.c_str(),
                     is_weight ? "the weight is not a positive number" : "the hold is not 0 to 1000 ms");
        std::exit(2);
      }
      if (is_weight) {
        out.push_back({item, "gbt", PsoConvention::Separate, v});
      } else {
        out.push_back({item, "gbt", PsoConvention::Separate, 0, PursuitHold{v / 1000, 0.3, 0.02}});
      }
    }
  }
  if (out.empty()) {
    std::fprintf(stderr, "bench_classify: --methods %s names no method\n", list.c_str());
    std::exit(2);
  }
  return out;
}

// Cost per sample, median and range over the table's cells, per method: the side-by-side figure.
void print_cost_summary(const std::vector<Method>& methods, const std::vector<std::vector<double>>& ns) {
  std::printf("\nCost per sample over the table's %zu cells (same run): median, min, max ns\n\n", ns.front().size());
  std::printf("| method | median ns | min ns | max ns |\n|---|---:|---:|---:|\n");
  for (std::size_t k = 0; k < methods.size(); ++k) {
    std::vector<double> v = ns[k];
    std::sort(v.begin(), v.end());
    std::printf("| %s | %.0f | %.0f | %.0f |\n", methods[k].name.c_str(), quantile(v, 0.5), v.front(), v.back());
  }
}

// The true saccades of a labelled stream that a method could lose among slower movements: a
// catch-up saccade (pursuit before it and after it and its PSO) and a microsaccade (fixation on
// both sides, under 1 deg between the mean gaze of the 10 samples before and after).
struct SmallSaccades {
  std::vector<std::pair<std::size_t, std::size_t>> catch_up, micro;  // [begin, end) sample runs
};

SmallSaccades small_saccades(const Labelled& l) {
  SmallSaccades out;
  const std::vector<Label>& t = l.truth;
  const auto mean_at = [&](std::size_t from, std::size_t to, double& x, double& y) {
    double n = 0;
    x = y = 0;
    for (std::size_t i = from; i < to; ++i)
      if (l.samples[i].valid) x += l.samples[i].x_deg, y += l.samples[i].y_deg, ++n;
    if (n > 0) x /= n, y /= n;
    return n > 0;
  };
  for (std::size_t a = 1; a < t.size();) {
    if (t[a] != Label::Saccade || t[a - 1] == Label::Saccade) {
      ++a;
      continue;
    }
    std::size_t b = a;
    while (b < t.size() && t[b] == Label::Saccade) ++b;
    std::size_t after = b;
    while (after < t.size() && t[after] == Label::Pso) ++after;
    if (after >= t.size()) break;
    const Label before_l = t[a - 1], after_l = t[after];
    if (before_l == Label::Pursuit && after_l == Label::Pursuit) out.catch_up.push_back({a, b});
    double x0, y0, x1, y1;
    if (before_l == Label::Fixation && after_l == Label::Fixation && a >= 10 && after + 10 <= t.size() &&
        mean_at(a - 10, a, x0, y0) && mean_at(after, after + 10, x1, y1) && std::hypot(x1 - x0, y1 - y0) < 1.0)
      out.micro.push_back({a, b});
    a = b;
  }
  return out;
}

// Found: a sample of the true saccade labelled saccade.
int found(const std::vector<std::pair<std::size_t, std::size_t>>& runs, const std::vector<Label>& p) {
  int n = 0;
  for (const auto& [a, b] : runs)
    n += std::any_of(p.begin() + static_cast<std::ptrdiff_t>(a), p.begin() + static_cast<std::ptrdiff_t>(b),
                     [](Label x) { return x == Label::Saccade; });
  return n;
}

void print_small_saccades(const std::vector<Method>& methods, const Condition& c, double seconds, int seeds) {
  std::printf("\nSmall saccades found, condition %s (found: a saccade label within the true saccade): catch-up "
              "saccades within pursuit, microsaccades (< 1 deg) within fixation.\n\n",
              c.name);
  std::printf("| rate Hz | method | catch-up found | of | %% | microsaccades found | of | %% |\n");
  std::printf("|---:|---|---:|---:|---:|---:|---:|---:|\n");
  for (const double rate : {60.0, 250.0, 500.0, 1000.0}) {
    const std::vector<Labelled> data = degraded(rate, c, seconds, seeds);
    for (const Method& m : methods) {
      int cu = 0, cu_n = 0, mi = 0, mi_n = 0;
      for (const Labelled& l : data) {
        const SmallSaccades truth = small_saccades(l);
        const std::vector<Label> p = classify_all(m.method, m.options(rate), l.samples);
        cu += found(truth.catch_up, p), cu_n += static_cast<int>(truth.catch_up.size());
        mi += found(truth.micro, p), mi_n += static_cast<int>(truth.micro.size());
      }
      const auto pct = [](int a, int n) { return n ? 100.0 * a / n : std::nan(""); };
      std::printf("| %.0f | %s | %d | %d | %.0f | %d | %d | %.0f |\n", rate, m.name.c_str(), cu, cu_n, pct(cu, cu_n), mi,
                  mi_n, pct(mi, mi_n));
      std::fflush(stdout);
    }
  }
}

}  // namespace

int main(int argc, char** argv) {
  double seconds = 120;
  int seeds = 3;
  std::string method_list;
  bool accuracy_only = false, small_only = false;
  for (int i = 1; i < argc; ++i) {
    const bool has_value = i + 1 < argc;
    if (std::strcmp(argv[i], "--seconds") == 0 && has_value) seconds = std::atof(argv[++i]);
    else if (std::strcmp(argv[i], "--seeds") == 0 && has_value) seeds = std::atoi(argv[++i]);
    else if (std::strcmp(argv[i], "--methods") == 0 && has_value) method_list = argv[++i];
    else if (std::strcmp(argv[i], "--accuracy-only") == 0) accuracy_only = true;
    else if (std::strcmp(argv[i], "--small-saccades") == 0) small_only = true;
    else {
      std::fprintf(stderr, "bench_classify: unknown or incomplete argument %s\n", argv[i]);
      return 2;
    }
  }
  const std::vector<Method> methods = chosen_methods(method_list);
  std::vector<std::vector<double>> cost_ns(methods.size());
  const double rates[] = {60, 250, 500, 1000};
  std::vector<Condition> conditions;
  conditions.push_back({"clean (0.03 deg)", {}});
  {
    Degradation d;
    d.extra_noise_deg = 0.1;
    conditions.push_back({"+0.1 deg noise", d});
    d.dropouts_per_s = 2;
    d.dropout_mean_s = 0.02;
    conditions.push_back({"+0.1 deg, drops 2/s", d});
    d.extra_noise_deg = 0.3;
    conditions.push_back({"+0.3 deg, drops 2/s", d});
    // Realistic: microsaccades, catch-up saccades, PSO, blink eye and lid movements; then the same
    // tracker noise (0.104 deg = 0.03 and 0.1 deg white together) coloured, and behind the filter.
    Degradation n;
    n.extra_noise_deg = 0.1;
    conditions.push_back({"realistic, +0.1 deg", n, true});
    conditions.push_back({"realistic, 0.104 deg noise of slope 1", {}, true, 0.104, 1.0});
    conditions.push_back({"realistic, 0.104 deg noise of slope 2", {}, true, 0.104, 2.0});
    n.heuristic_filter = true;
    conditions.push_back({"realistic, +0.1 deg, heuristic filter", n, true});
  }
  const Condition& noisy = conditions[1];
  const Condition& realistic = conditions[4];
  const Condition& pink = conditions[5];
  const Condition& filtered = conditions[7];
  if (small_only) {
    print_small_saccades(methods, realistic, seconds, seeds);
    return 0;
  }

  std::printf("Synthetic gaze, %d seed(s) x %.0f s per cell; kappa = sample-level Cohen's kappa of the class vs the "
              "rest; 'all' = Cohen's kappa over all labels.\n",
              seeds, seconds);
  std::printf("Generator noise is 0.03 deg RMS per axis (0.06 during saccades) unless a condition sets it (with its "
              "spectral slope: power ~ 1/f^slope); conditions add gaussian noise per axis and drop runs of samples "
              "(exponential length, mean 20 ms).\n\n");
  std::printf("| rate Hz | condition | method | fixation | saccade | pso | pursuit | blink | all | pso %% | unknown %% | "
              "ns/sample | latency ms |\n");
  std::printf("|---:|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
  // What a method does once per process (gbt parses its compiled-in model, ~2 MB of text) is not a
  // cost per sample: done before the first timed cell, which it made look twice as slow.
  for (const Method& m : methods) make_classifier(m.method, m.options(rates[0]));
  for (const double rate : rates) {
    for (const Condition& c : conditions) {
      const std::vector<Labelled> data = degraded(rate, c, seconds, seeds);  // the same for every method
      for (std::size_t mi = 0; mi < methods.size(); ++mi) {
        const Method& m = methods[mi];
        std::vector<Label> truth, predicted;
        double ns = 0;
        std::size_t n = 0;
        for (const Labelled& l : data) {
          const auto t0 = std::chrono::steady_clock::now();
          const std::vector<Label> p = classify_all(m.method, m.options(rate), l.samples);
          ns += static_cast<double>(
              std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now() - t0).count());
          n += l.samples.size();
          truth.insert(truth.end(), l.truth.begin(), l.truth.end());
          predicted.insert(predicted.end(), p.begin(), p.end());
        }
        double pso = 0, unknown = 0;
        for (const Label p : predicted) {
          pso += p == Label::Pso ? 1 : 0;
          unknown += p == Label::Unknown ? 1 : 0;
        }
        const double total = static_cast<double>(predicted.size());
        std::printf("| %.0f | %s | %s | %s | %s | %s | %s | %s | %s | %.1f | %.1f | %.0f | %.0f |\n", rate, c.name,
                    m.name.c_str(), fmt(class_kappa(truth, predicted, Label::Fixation)).c_str(),
                    fmt(class_kappa(truth, predicted, Label::Saccade)).c_str(),
                    fmt(class_kappa(truth, predicted, Label::Pso)).c_str(),
                    fmt(class_kappa(truth, predicted, Label::Pursuit)).c_str(),
                    fmt(class_kappa(truth, predicted, Label::Blink)).c_str(),
                    fmt(overall_kappa(truth, predicted)).c_str(), 100 * pso / total, 100 * unknown / total,
                    ns / static_cast<double>(n), make_classifier(m.method, m.options(rate))->latency_s() * 1000);
        cost_ns[mi].push_back(ns / static_cast<double>(n));
        std::fflush(stdout);
      }
    }
  }
  print_cost_summary(methods, cost_ns);
  if (accuracy_only) return 0;
  print_small_saccades(methods, realistic, seconds, seeds);
  print_event_f1(rates, {&noisy, &realistic, &pink, &filtered}, seconds, seeds);
  print_onset_latency(rates, noisy, seconds, seeds);
  print_onset_latency(rates, realistic, seconds, seeds);
  print_provisional(rates, noisy, seconds, seeds);
  print_provisional(rates, realistic, seconds, seeds);
  print_provisional(rates, filtered, seconds, seeds);
  return 0;
}
