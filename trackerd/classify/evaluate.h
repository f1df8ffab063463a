// SPDX-License-Identifier: Apache-2.0
#pragma once
// Measuring a classifier against ground truth, and degrading clean data the way real trackers do
// (used by the benchmark and the tests; no dependency on any source).
#include <array>
#include <cstdint>
#include <random>
#include <vector>

#include "classify/classifier.h"
#include "classify/provisional.h"

namespace fovea::trackerd::classify {

// Cohen's kappa of one class against the rest (sample level): kappa = (p_o - p_e) / (1 - p_e).
// NaN when the class occurs in neither sequence or in every sample of both (kappa undefined).
double class_kappa(const std::vector<Label>& truth, const std::vector<Label>& predicted, Label c);
// Cohen's kappa over all seven labels at once.
double overall_kappa(const std::vector<Label>& truth, const std::vector<Label>& predicted);

// Event-level F1 of class c (Startsev, Agtzidis & Dorr 2019; Hooge et al. 2018): events are runs of
// c; a true and a predicted event match when their intersection over union (in samples) is at
// least min_iou, each used once; F1 = 2 hits / (2 hits + misses + false events). NaN when neither
// sequence has an event of c. (bench/eval_classify_human.py computes the same on real data.)
double event_f1(const std::vector<Label>& truth, const std::vector<Label>& predicted, Label c, double min_iou = 0.5);

// How long after a true event's onset the classifier said so: for each run of class c in `truth`,
// the first predicted sample of c in the predicted run that overlaps it (it may start a little
// before the true onset), and the time its label became final (classify_online) minus the true
// onset's time. A true run that no predicted run of c overlaps is missed.
struct OnsetLatency {
  std::vector<double> latency_s;  // one per found onset
  std::size_t missed = 0;
};
OnsetLatency onset_latency(const std::vector<Label>& truth, const std::vector<Label>& predicted,
                           const std::vector<double>& final_t_s, const std::vector<Sample>& samples, Label c);
// How long after a true onset the provisional events (provisional.h) said so: for each true saccade
// (a run of Saccade in `truth`), the first provisional Saccade Start whose onset lies within 20 ms
// before it to its end; for each true fixation that follows a saccade (directly or after its PSO),
// the first provisional Fixation Start whose time lies within 20 ms before to 50 ms after the
// landing (the saccade's last sample's successor). Latency =
// the newest sample's time when the event was known (emitted_s) minus the true onset. `false_starts`:
// provisional saccade starts matched to no true saccade.
struct ProvisionalLatency {
  OnsetLatency saccade, fixation;
  std::size_t false_starts = 0;
};
ProvisionalLatency provisional_latency(const std::vector<Label>& truth, const std::vector<Sample>& samples,
                                       const std::vector<ProvisionalEvent>& events);
// Provisional events against a method's final labels, as the daemon checks them (ProvisionalCheck,
// PSO counted as saccade): how many the final events confirmed and how many were retracted.
struct ProvisionalAgreement {
  std::uint64_t emitted = 0, confirmed = 0, retracted = 0;
};
ProvisionalAgreement provisional_agreement(const std::vector<ProvisionalEvent>& events, const std::vector<Label>& final_labels,
                                           const std::vector<Sample>& samples);

// The q-quantile (0..1, nearest rank) of `v`; NaN when empty.
double quantile(std::vector<double> v, double q);

struct Degradation {
  double extra_noise_deg = 0;      // added gaussian noise, per axis, degrees (RMS)
  double dropouts_per_s = 0;       // Poisson rate of runs of lost samples
  double dropout_mean_s = 0.020;   // mean length of a run (exponential), capped at 10x
  // The tracker's own heuristic filter on its output, after the noise: Stampe 1993 (Behav Res
  // Methods Instrum Comput 25:137-142), the first stage, which is EyeLink's "standard" level (one
  // sample of delay; SR Research's default for link data): a sample that lies beyond both its
  // neighbours (a one-sample spike) takes the value of the nearer one. Unfiltered tracker noise is
  // white; filters like this one colour it (Niehorster, Zemblys & Holmqvist 2021, Behav Res Methods
  // 53:311-324), and coloured noise passes for drift.
  bool heuristic_filter = false;
  std::uint64_t seed = 7;
};
// Adds noise, applies the heuristic filter, and drops runs of samples to invalid (x, y set to NaN).
// Times are untouched.
void degrade(std::vector<Sample>& samples, const Degradation& d);
// Stampe 1993's first stage on x and y separately, over runs of valid samples.
void stampe_filter(std::vector<Sample>& samples);

}  // namespace fovea::trackerd::classify
