// SPDX-License-Identifier: Apache-2.0
#include "classify/classifier.h"

#include <cmath>
#include <limits>
#include <stdexcept>

#include "classify/pipeline.h"
#include "classify/trees_core.h"

namespace fovea::trackerd::classify {

const char* to_string(PsoConvention c) {
  switch (c) {
    case PsoConvention::Separate: return "separate";
    case PsoConvention::Onset: return "onset";
    case PsoConvention::None: return "none";
  }
  return "separate";
}

std::optional<PsoConvention> pso_convention(const std::string& name) {
  for (const PsoConvention c : {PsoConvention::Separate, PsoConvention::Onset, PsoConvention::None}) {
    if (name == to_string(c)) return c;
  }
  return std::nullopt;
}

const char* to_string(Label l) {
  switch (l) {
    case Label::Fixation: return "fixation";
    case Label::Saccade: return "saccade";
    case Label::Pso: return "pso";
    case Label::Pursuit: return "pursuit";
    case Label::Blink: return "blink";
    case Label::Lost: return "lost";
    case Label::Unknown: return "unknown";
  }
  return "unknown";
}

const std::vector<ClassifierInfo>& classifiers() {
  static const std::vector<ClassifierInfo> all = {
      {"gbt",
       "gradient-boosted trees (issue 43) over multi-scale speed, direction-consistency and dispersion "
       "features (Larsson et al. 2015; Startsev et al. 2019) of 256 ms before and 64 ms after each sample "
       "(--offline: 256 ms after), then over the first trees' class probabilities around it, trained on "
       "GazeCom's expert labels and copies of them as other trackers would record them "
       "(bench/train_classifier.py), smoothed; PSO, and saccades the trees leave in fixations, by ivvt's rule; "
       "gap fill-in 75 ms"},
      {"ivvt",
       "I-VVT (Komogortsev & Karpov 2013): saccades by a noise-adaptive velocity threshold with onset/offset "
       "and PSO detection after Nystrom & Holmqvist 2010; pursuit vs fixation by low-pass velocity as in "
       "REMoDNaV (Dar et al. 2021); gap fill-in 75 ms"},
      {"ivt",
       "I-VT after the Tobii I-VT filter (Olsen 2012): 20 ms velocity window, 30 deg/s, gap fill-in 75 ms, "
       "merge fixations within 75 ms and 0.5 deg, discard fixations under 60 ms"},
      {"idt", "I-DT (Salvucci & Goldberg 2000): dispersion <= 1.0 deg over >= 100 ms is a fixation, else saccade"},
      {"lee2009",
       "Lee 2009 sec. 3.5.2 (the seed's rule): normalized speed per 60 Hz frame < 0.03 fixation, > 0.1 saccade, "
       "between drift (labelled pursuit); pupil aspect < 0.7 blink"},
  };
  return all;
}

namespace {

std::string known_names() {
  std::string s;
  for (const auto& c : classifiers()) s += (s.empty() ? "" : ", ") + c.name;
  return s;
}

}  // namespace

std::string check(const PursuitHold& h) {
  if (!(h.hold_s >= 0 && h.hold_s <= 1)) return "a pursuit hold of " + std::to_string(h.hold_s) + " s is not in [0, 1] s";
  if (!(h.ratio > 0 && h.ratio <= 1)) return "a pursuit hold's ratio " + std::to_string(h.ratio) + " is not in (0, 1]";
  if (!(h.min_s >= 0 && h.min_s <= 1)) {
    return "a pursuit hold's least pursuit of " + std::to_string(h.min_s) + " s is not in [0, 1] s";
  }
  return {};
}

std::unique_ptr<OnlineClassifier> make_classifier(const std::string& name, const ClassifierOptions& options) {
  if (!std::isfinite(options.nominal_rate_hz) || options.nominal_rate_hz <= 0) {
    throw std::invalid_argument("classifier " + name + ": nominal rate " + std::to_string(options.nominal_rate_hz) +
                                " Hz is not a positive number");
  }
  if (const std::string err = protocol::validate(options.display); !err.empty()) {
    throw std::invalid_argument("classifier " + name + ": display geometry: " + err);
  }
  if (options.pso != PsoConvention::Separate && name != "gbt") {
    throw std::invalid_argument("classifier " + name + ": only gbt takes a PSO convention (pso " +
                                to_string(options.pso) + "; " + name + "'s PSO is part of its rule)");
  }
  if (!(options.pursuit_weight >= 0 && std::isfinite(options.pursuit_weight))) {
    throw std::invalid_argument("classifier " + name + ": pursuit weight " + std::to_string(options.pursuit_weight) +
                                " is neither 0 (the model's) nor a positive number");
  }
  if (options.pursuit_weight > 0 && name != "gbt") {
    throw std::invalid_argument("classifier " + name + ": only gbt weighs its classes (" + name +
                                "'s pursuit is a rule's)");
  }
  if (options.pursuit_hold) {
    if (const std::string err = check(*options.pursuit_hold); !err.empty()) {
      throw std::invalid_argument("classifier " + name + ": " + err);
    }
  }
  if (options.pursuit_hold && options.pursuit_hold->hold_s > 0 && name != "gbt") {
    throw std::invalid_argument("classifier " + name + ": only gbt holds doubtful fixations (" + name +
                                "'s pursuit is a rule's)");
  }
  const FrontendOptions standard;  // 75 ms gap fill-in, blink for losses up to 0.5 s
  if (name == "gbt") {
    GbtOptions o;
    o.offline = options.offline;
    o.trees_only = options.trees_only;
    o.pso = options.pso;
    o.pursuit_weight = options.pursuit_weight;
    o.pursuit_hold = options.pursuit_hold;
    return make_trees_pipeline(options.model_path.empty() ? builtin_gbt_model() : load_gbt_model(options.model_path),
                               options.display, std::move(o));
  }
  if (name == "ivvt") return std::make_unique<Pipeline>(name, standard, make_ivvt_core());
  if (name == "ivt") return std::make_unique<Pipeline>(name, standard, make_ivt_core());
  if (name == "idt") {
    // I-DT's "saccade" is whatever is not a fixation, noise included: next to a blink it is no
    // evidence of the lid (on noisy synthetic gaze the lid rule made half its blinks false).
    FrontendOptions idt = standard;
    idt.lid_opening_max_s = 0;
    return std::make_unique<Pipeline>(name, idt, make_idt_core());
  }
  if (name == "lee2009") {
    // The seed's rule as published: no fill-in, blinks only from the pupil aspect ratio.
    FrontendOptions lee;
    lee.gap_fill_max_s = 0;
    lee.loss_blink_max_s = 0;
    lee.lid_opening_max_s = 0;
    return std::make_unique<Pipeline>(name, lee, make_lee_core(options.display));
  }
  throw std::invalid_argument("unknown classification method \"" + name + "\" (known: " + known_names() + ")");
}

std::unique_ptr<OnlineClassifier> make_classifier(const std::string& name, double nominal_rate_hz) {
  ClassifierOptions o;
  o.nominal_rate_hz = nominal_rate_hz;
  return make_classifier(name, o);
}

OnlineLabels classify_online(const std::string& name, const ClassifierOptions& options,
                             const std::vector<Sample>& samples) {
  auto c = make_classifier(name, options);
  OnlineLabels r{std::vector<Label>(samples.size(), Label::Unknown),
                 std::vector<double>(samples.size(), std::numeric_limits<double>::quiet_NaN())};
  std::vector<Labeled> out;
  double newest = std::numeric_limits<double>::quiet_NaN();
  const auto take = [&] {
    for (const Labeled& l : out) {
      r.labels.at(l.index) = l.label;
      r.final_t_s.at(l.index) = newest;
    }
    out.clear();
  };
  for (const Sample& s : samples) {
    if (std::isfinite(s.t_s) && !(s.t_s <= newest)) newest = s.t_s;
    c->push(s, out);
    take();
  }
  c->flush(out);
  take();
  return r;
}

std::vector<Label> classify_all(const std::string& name, const ClassifierOptions& options,
                                const std::vector<Sample>& samples) {
  return classify_online(name, options, samples).labels;
}

std::vector<Label> classify_all(const std::string& name, double nominal_rate_hz, const std::vector<Sample>& samples) {
  ClassifierOptions o;
  o.nominal_rate_hz = nominal_rate_hz;
  return classify_all(name, o, samples);
}

}  // namespace fovea::trackerd::classify
