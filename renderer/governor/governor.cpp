// SPDX-License-Identifier: Apache-2.0
#include "governor/governor.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <sstream>
#include <stdexcept>

#include <nlohmann/json.hpp>

namespace fovea::render {

extern const char* const kBuiltinFrontsJson;  // fronts_data.cpp, generated from fronts.json

namespace {

using Json = nlohmann::json;

const Json& field(const Json& j, const char* key, const std::string& where) {
  if (!j.is_object() || !j.contains(key)) throw std::invalid_argument(where + ": missing \"" + key + "\"");
  return j.at(key);
}

std::string text(const Json& j, const char* key, const std::string& where) {
  const Json& v = field(j, key, where);
  if (!v.is_string()) throw std::invalid_argument(where + "." + key + ": must be a string");
  return v.get<std::string>();
}

double number(const Json& j, const char* key, const std::string& where, double lo) {
  const Json& v = field(j, key, where);
  if (!v.is_number() || !std::isfinite(v.get<double>()) || v.get<double>() < lo) {
    char bound[48];
    std::snprintf(bound, sizeof bound, "%g", lo);
    throw std::invalid_argument(where + "." + key + ": must be a finite number >= " + (lo == -1e300 ? std::string("-inf") : bound));
  }
  return v.get<double>();
}

bool flag(const Json& j, const char* key, const std::string& where) {
  const Json& v = field(j, key, where);
  if (!v.is_boolean()) throw std::invalid_argument(where + "." + key + ": must be true or false");
  return v.get<bool>();
}

PassId pass_of(const std::string& effect) {
  if (effect == "dof") return PassId::Dof;
  if (effect == "gi") return PassId::Gi;
  if (effect == "attention") return PassId::Attention;
  return PassId::LodSelect;
}

double utility(const Front& f, const FrontOption& o) {
  double lo = o.accuracy, hi = o.accuracy;
  for (const FrontOption& x : f.options) {
    lo = std::min(lo, x.accuracy);
    hi = std::max(hi, x.accuracy);
  }
  if (!(hi > lo)) return 1.0;
  const double u = (o.accuracy - lo) / (hi - lo);
  return f.higher_better ? u : 1.0 - u;
}

}  // namespace

std::vector<Front> parse_fronts(const std::string& json_text, const std::string& origin) {
  Json root;
  try {
    root = Json::parse(json_text);
  } catch (const Json::parse_error& e) {
    throw std::invalid_argument(origin + ": not JSON: " + e.what());
  }
  const Json& list = field(root, "fronts", origin);
  if (!list.is_array()) throw std::invalid_argument(origin + ".fronts: must be a list");
  std::vector<Front> fronts;
  Settings probe;
  for (std::size_t i = 0; i < list.size(); ++i) {
    const std::string where = origin + ".fronts[" + std::to_string(i) + "]";
    const Json& j = list[i];
    Front f;
    f.effect = text(j, "effect", where);
    if (f.effect != "dof" && f.effect != "gi" && f.effect != "attention" && f.effect != "lod")
      throw std::invalid_argument(where + ".effect: \"" + f.effect + "\" is not one of dof, gi, attention, lod");
    if (j.contains("backend")) f.backend = text(j, "backend", where);
    if (j.contains("device")) f.device = text(j, "device", where);
    const Json& passes = field(j, "passes", where);
    if (!passes.is_array() || passes.empty()) throw std::invalid_argument(where + ".passes: must be a non-empty list of pass names");
    for (const Json& p : passes) {
      if (!p.is_string()) throw std::invalid_argument(where + ".passes: must be a list of pass names");
      f.passes.push_back(p.get<std::string>());
    }
    f.metric = text(j, "metric", where);
    f.reference = text(j, "reference", where);
    if (j.contains("source")) f.source = text(j, "source", where);
    f.higher_better = flag(j, "higher_better", where);
    f.scales_with_pixels = flag(j, "scales_with_pixels", where);
    f.pixels = number(j, "pixels", where, 0);
    if (f.scales_with_pixels && !(f.pixels > 0)) throw std::invalid_argument(where + ".pixels: must be > 0 when scales_with_pixels");
    const Json& options = field(j, "options", where);
    if (!options.is_array() || options.empty()) throw std::invalid_argument(where + ".options: must be a non-empty list");
    for (std::size_t k = 0; k < options.size(); ++k) {
      const std::string ow = where + ".options[" + std::to_string(k) + "]";
      FrontOption o;
      o.label = text(options[k], "label", ow);
      o.ms = number(options[k], "ms", ow, 0);
      o.accuracy = number(options[k], "accuracy", ow, -1e300);
      const Json& settings = field(options[k], "settings", ow);
      if (!settings.is_object()) throw std::invalid_argument(ow + ".settings: must be an object of render settings");
      for (const auto& [key, value] : settings.items()) {
        if (!value.is_string()) throw std::invalid_argument(ow + ".settings." + key + ": must be a string");
        try {
          probe.set(key, value.get<std::string>());
        } catch (const std::exception& e) {
          throw std::invalid_argument(ow + ".settings: " + e.what());
        }
        o.settings[key] = value.get<std::string>();
      }
      f.options.push_back(std::move(o));
    }
    std::sort(f.options.begin(), f.options.end(), [](const FrontOption& a, const FrontOption& b) { return a.ms < b.ms; });
    fronts.push_back(std::move(f));
  }
  return fronts;
}

std::vector<Front> load_fronts(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error("cannot read fronts file " + path);
  std::stringstream ss;
  ss << in.rdbuf();
  return parse_fronts(ss.str(), path);
}

const std::vector<Front>& builtin_fronts() {
  static const std::vector<Front> fronts = parse_fronts(kBuiltinFrontsJson, "renderer/governor/fronts.json");
  return fronts;
}

Governor::Governor(double budget_ms, std::vector<Front> fronts) : budget_ms_(budget_ms), fronts_(std::move(fronts)) {
  set_budget_ms(budget_ms);
}

void Governor::set_budget_ms(double ms) {
  if (!std::isfinite(ms) || ms <= 0) throw std::invalid_argument("budget: must be a finite number of milliseconds > 0");
  budget_ms_ = ms;
  state_.budget_ms = ms;
  frames_since_plan_ = replan_frames;  // re-plan before the next frame
}

double Governor::predicted(const Front& f, const FrontOption& o) const {
  const double scale = f.scales_with_pixels && f.pixels > 0 && pixels_ > 0 ? pixels_ / f.pixels : 1.0;
  const auto it = correction_.find(f.effect);
  return o.ms * scale * (it == correction_.end() ? 1.0 : it->second);
}

void Governor::apply(const FramePlan& plan, const std::string& backend, const std::string& device, std::uint32_t width,
                     std::uint32_t height, Settings& settings) {
  std::vector<const Front*> active;
  for (const Front& f : fronts_) {
    if (!plan.runs(pass_of(f.effect))) continue;
    if (!f.backend.empty() && f.backend != backend) continue;
    if (!f.device.empty() && device.find(f.device) == std::string::npos) continue;
    const bool seen = std::any_of(active.begin(), active.end(), [&](const Front* a) { return a->effect == f.effect; });
    if (!seen) active.push_back(&f);
  }
  const double pixels = static_cast<double>(width) * static_cast<double>(height);
  if (active != active_ || pixels != pixels_ || frames_since_plan_ >= replan_frames || over_) {
    active_ = active;
    pixels_ = pixels;
    this->plan();
  }
  for (const Front* f : active_) {
    const auto it = chosen_.find(f->effect);
    if (it == chosen_.end()) continue;
    for (const auto& [key, value] : f->options[it->second].settings) settings.set(key, value);
  }
}

void Governor::plan() {
  frames_since_plan_ = 0;
  over_ = false;
  ++state_.replans;
  const double other = other_ms_ > 0 ? other_ms_ : 0.0;
  const double available = budget_ms_ - other;
  // Every combination of one option per active effect (a few thousand at most).
  std::vector<std::size_t> pick(active_.size(), 0), best, cheapest;
  double best_utility = -1, best_cost = std::numeric_limits<double>::infinity();
  double cheapest_cost = std::numeric_limits<double>::infinity();
  double current_utility = -1, current_cost = std::numeric_limits<double>::infinity();
  bool current_valid = !active_.empty();
  std::vector<std::size_t> current;
  for (const Front* f : active_) {
    const auto it = chosen_.find(f->effect);
    if (it == chosen_.end()) current_valid = false;
    else current.push_back(it->second);
  }
  while (true) {
    double cost = 0, util = 0;
    for (std::size_t e = 0; e < active_.size(); ++e) {
      cost += predicted(*active_[e], active_[e]->options[pick[e]]);
      util += utility(*active_[e], active_[e]->options[pick[e]]);
    }
    if (cost <= available && (util > best_utility + 1e-12 || (std::abs(util - best_utility) <= 1e-12 && cost < best_cost))) {
      best = pick;
      best_utility = util;
      best_cost = cost;
    }
    if (cost < cheapest_cost) {
      cheapest = pick;
      cheapest_cost = cost;
    }
    if (current_valid && pick == current) {
      current_utility = util;
      current_cost = cost;
    }
    std::size_t e = 0;
    while (e < active_.size() && ++pick[e] == active_[e]->options.size()) pick[e++] = 0;
    if (e == active_.size()) break;
  }
  state_.cannot_meet = best.empty() && !active_.empty();
  std::vector<std::size_t> take = state_.cannot_meet ? cheapest : best;
  // Keep the current choice while it fits and is nearly as good (no flicker between neighbours).
  if (!state_.cannot_meet && current_valid && current_cost <= available && current_utility >= best_utility - 0.05) take = current;
  chosen_.clear();
  for (std::size_t e = 0; e < active_.size(); ++e) chosen_[active_[e]->effect] = take[e];
  state_.choices.clear();
  state_.predicted_ms = other;
  for (std::size_t e = 0; e < active_.size(); ++e) {
    const Front& f = *active_[e];
    const FrontOption& o = f.options[take[e]];
    Choice c;
    c.effect = f.effect;
    c.label = o.label;
    c.metric = f.metric;
    c.accuracy = o.accuracy;
    c.predicted_ms = predicted(f, o);
    const auto it = correction_.find(f.effect);
    c.correction = it == correction_.end() ? 1.0 : it->second;
    state_.predicted_ms += c.predicted_ms;
    state_.choices.push_back(c);
  }
}

void Governor::observe(const PassTimer& timer) {
  // A stereo frame's right eye records its passes as "right.<pass>" (0 when there is none).
  const auto both_eyes = [&timer](const std::string& pass) { return timer.frame_ms(pass) + timer.frame_ms("right." + pass); };
  const double frame = both_eyes("frame");
  double governed = 0;
  for (const Front* f : active_) {
    double measured = 0;
    for (const std::string& p : f->passes) measured += both_eyes(p);
    governed += measured;
    const auto it = chosen_.find(f->effect);
    if (it == chosen_.end() || !(measured > 0)) continue;
    const FrontOption& o = f->options[it->second];
    const double scale = f->scales_with_pixels && f->pixels > 0 && pixels_ > 0 ? pixels_ / f->pixels : 1.0;
    const double raw = o.ms * scale;
    if (!(raw > 0)) continue;
    const double ratio = std::clamp(measured / raw, 1e-4, 1e4);
    auto c = correction_.find(f->effect);
    if (c == correction_.end()) correction_[f->effect] = ratio;
    else c->second = 0.7 * c->second + 0.3 * ratio;
  }
  if (frame > 0) {
    const double other = std::max(0.0, frame - governed);
    other_ms_ = other_ms_ < 0 ? other : 0.8 * other_ms_ + 0.2 * other;
  }
  state_.measured_ms = frame;
  state_.other_ms = std::max(0.0, other_ms_);
  state_.predicted_ms = state_.other_ms;
  for (Choice& c : state_.choices) {
    for (const Front* f : active_)
      if (f->effect == c.effect) c.predicted_ms = predicted(*f, f->options[chosen_[f->effect]]);
    const auto it = correction_.find(c.effect);
    c.correction = it == correction_.end() ? 1.0 : it->second;
    state_.predicted_ms += c.predicted_ms;
  }
  ++frames_since_plan_;
  if (frame > 1.2 * budget_ms_) over_ = true;
}

std::string Governor::State::summary() const {
  char head[160];
  std::snprintf(head, sizeof head, "budget %.1f ms, predicted %.1f, last %.1f%s", budget_ms, predicted_ms, measured_ms,
                cannot_meet ? " (cannot meet it: cheapest settings)" : "");
  std::string out = head;
  if (choices.empty()) return out + ": no governed effect runs";
  for (std::size_t i = 0; i < choices.size(); ++i) {
    const Choice& c = choices[i];
    char part[200];
    std::snprintf(part, sizeof part, "%s %s %s (%.3g %s, %.1f ms)", i == 0 ? ":" : ";", c.effect.c_str(), c.label.c_str(),
                  c.accuracy, c.metric.c_str(), c.predicted_ms);
    out += part;
  }
  return out;
}

}  // namespace fovea::render
