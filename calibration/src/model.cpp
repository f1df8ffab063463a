// SPDX-License-Identifier: Apache-2.0
#include "fovea/calib/model.h"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cerrno>
#include <cstring>
#include <ctime>
#include <fstream>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <system_error>

#include "fovea/calib/bilinear_grid.h"
#include "fovea/calib/poly2.h"

namespace fovea::calib {

namespace {

using nlohmann::json;

// --- reading fields, with errors that name where ---

[[noreturn]] void bad(const std::string& where, const std::string& field, const std::string& what) {
  throw std::invalid_argument(where + ": field '" + field + "' " + what);
}

const json& member(const json& j, const std::string& where, const std::string& field) {
  if (!j.is_object()) throw std::invalid_argument(where + ": must be a JSON object");
  const auto it = j.find(field);
  if (it == j.end()) bad(where, field, "is missing");
  return *it;
}

double number(const json& v, const std::string& where, const std::string& field) {
  if (!v.is_number()) bad(where, field, "must be a number");
  const double d = v.get<double>();
  if (!std::isfinite(d)) bad(where, field, "must be finite");
  return d;
}

std::vector<double> numbers(const json& j, const std::string& where, const std::string& field, std::size_t size) {
  const json& v = member(j, where, field);
  if (!v.is_array() || (size != 0 && v.size() != size)) {
    bad(where, field, size ? "must be an array of " + std::to_string(size) + " numbers" : "must be an array of numbers");
  }
  std::vector<double> out;
  for (std::size_t i = 0; i < v.size(); ++i) out.push_back(number(v[i], where, field + "[" + std::to_string(i) + "]"));
  return out;
}

// --- the models ---

class Poly2Model final : public CalibrationModel {
 public:
  explicit Poly2Model(Poly2Map m) : m_(m) {}
  Point apply(Point raw) const override { return m_.apply(raw); }
  std::string kind() const override { return "poly2"; }
  json to_json() const override {
    return {{"kind", kind()},
            {"centre", {m_.centre.x, m_.centre.y}},
            {"scale", {m_.scale.x, m_.scale.y}},
            {"coeff_x", m_.coeff_x},
            {"coeff_y", m_.coeff_y}};
  }
  FitStats stats() const override { return {m_.points, m_.condition, m_.rms_residual, m_.max_residual}; }
  std::unique_ptr<CalibrationModel> clone() const override { return std::make_unique<Poly2Model>(*this); }

  static std::unique_ptr<CalibrationModel> from_json(const json& j, const std::string& where) {
    Poly2Map m;
    const auto c = numbers(j, where, "centre", 2), s = numbers(j, where, "scale", 2);
    m.centre = {c[0], c[1]};
    m.scale = {s[0], s[1]};
    if (!(m.scale.x > 0) || !(m.scale.y > 0)) bad(where, "scale", "must be positive");
    const auto cx = numbers(j, where, "coeff_x", Poly2Map::kTerms), cy = numbers(j, where, "coeff_y", Poly2Map::kTerms);
    std::copy(cx.begin(), cx.end(), m.coeff_x.begin());
    std::copy(cy.begin(), cy.end(), m.coeff_y.begin());
    return std::make_unique<Poly2Model>(m);
  }

 private:
  Poly2Map m_;
};

class AffineModel final : public CalibrationModel {
 public:
  explicit AffineModel(AffineMap m) : m_(m) {}
  Point apply(Point raw) const override { return m_.apply(raw); }
  std::string kind() const override { return "affine"; }
  json to_json() const override { return {{"kind", kind()}, {"a", m_.a}}; }
  FitStats stats() const override { return m_.stats; }
  std::unique_ptr<CalibrationModel> clone() const override { return std::make_unique<AffineModel>(*this); }

  static std::unique_ptr<CalibrationModel> from_json(const json& j, const std::string& where) {
    AffineMap m;
    const auto a = numbers(j, where, "a", AffineMap::kParams);
    std::copy(a.begin(), a.end(), m.a.begin());
    return std::make_unique<AffineModel>(m);
  }

 private:
  AffineMap m_;
};

class HomographyModel final : public CalibrationModel {
 public:
  explicit HomographyModel(HomographyMap m) : m_(m) {}
  Point apply(Point raw) const override { return m_.apply(raw); }
  std::string kind() const override { return "homography"; }
  json to_json() const override { return {{"kind", kind()}, {"h", m_.h}}; }
  FitStats stats() const override { return m_.stats; }
  std::unique_ptr<CalibrationModel> clone() const override { return std::make_unique<HomographyModel>(*this); }

  static std::unique_ptr<CalibrationModel> from_json(const json& j, const std::string& where) {
    HomographyMap m;
    const auto h = numbers(j, where, "h", 9);
    std::copy(h.begin(), h.end(), m.h.begin());
    return std::make_unique<HomographyModel>(m);
  }

 private:
  HomographyMap m_;
};

class GridModel final : public CalibrationModel {
 public:
  explicit GridModel(BilinearGrid g) : g_(std::move(g)) {}
  Point apply(Point raw) const override { return g_.apply(raw); }
  std::string kind() const override { return "bilinear-grid"; }
  json to_json() const override {
    json v = json::array();
    for (const Point& p : g_.vectors) v.push_back({p.x, p.y});
    return {{"kind", kind()}, {"xs", g_.xs}, {"ys", g_.ys}, {"vectors", v}};
  }
  FitStats stats() const override { return g_.stats; }
  std::unique_ptr<CalibrationModel> clone() const override { return std::make_unique<GridModel>(*this); }

  static std::unique_ptr<CalibrationModel> from_json(const json& j, const std::string& where) {
    BilinearGrid g;
    g.xs = numbers(j, where, "xs", 0);
    g.ys = numbers(j, where, "ys", 0);
    for (const auto* axis : {&g.xs, &g.ys}) {
      const std::string name = axis == &g.xs ? "xs" : "ys";
      if (axis->size() < 2) bad(where, name, "must hold at least 2 grid coordinates");
      for (std::size_t i = 1; i < axis->size(); ++i) {
        if (!((*axis)[i] > (*axis)[i - 1])) bad(where, name, "must be strictly increasing");
      }
    }
    const json& v = member(j, where, "vectors");
    const std::size_t n = g.xs.size() * g.ys.size();
    if (!v.is_array() || v.size() != n) {
      bad(where, "vectors", "must be an array of " + std::to_string(n) + " [x, y] pairs (xs.size() * ys.size())");
    }
    for (std::size_t i = 0; i < n; ++i) {
      const std::string f = "vectors[" + std::to_string(i) + "]";
      if (!v[i].is_array() || v[i].size() != 2) bad(where, f, "must be an [x, y] pair");
      g.vectors.push_back({number(v[i][0], where, f + "[0]"), number(v[i][1], where, f + "[1]")});
    }
    g.stats.condition = std::numeric_limits<double>::quiet_NaN();
    return std::make_unique<GridModel>(std::move(g));
  }

 private:
  BilinearGrid g_;
};

}  // namespace

const std::vector<std::string>& model_kinds() {
  static const std::vector<std::string> kinds{"poly2", "affine", "homography", "bilinear-grid"};
  return kinds;
}

namespace {
std::string kinds_list() {
  std::string s;
  for (const auto& k : model_kinds()) s += (s.empty() ? "" : ", ") + k;
  return s;
}
}  // namespace

namespace {

std::unique_ptr<CalibrationModel> fit_once(std::string_view kind, std::span<const Correspondence> pts) {
  if (kind == "poly2") return std::make_unique<Poly2Model>(Poly2Map::fit(pts));
  if (kind == "affine") return std::make_unique<AffineModel>(AffineMap::fit(pts));
  if (kind == "homography") return std::make_unique<HomographyModel>(HomographyMap::fit(pts));
  if (kind == "bilinear-grid") return std::make_unique<GridModel>(BilinearGrid::fit(pts));
  throw std::invalid_argument("unknown calibration model '" + std::string(kind) + "' (known: " + kinds_list() + ")");
}

std::size_t parameters_of(std::string_view kind) {
  if (kind == "poly2") return 2 * Poly2Map::kTerms;
  if (kind == "affine") return 6;
  if (kind == "homography") return 8;
  return 0;
}

double median_of(std::vector<double> v) {
  const std::size_t mid = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(mid), v.end());
  return v[mid];
}

}  // namespace

ModelFit fit_model(std::string_view kind, std::span<const Correspondence> pts, const FitOptions& options) {
  // Several noisy samples per target make the design matrix full rank numerically even when there
  // are fewer distinct targets than the model has terms per axis; such a fit is determined by noise.
  const std::size_t terms = kind == "poly2" ? Poly2Map::kTerms : kind == "affine" ? 3 : kind == "homography" ? 4 : 0;
  if (terms > 0 && pts.size() >= 2 * terms) {
    std::vector<std::pair<double, double>> targets;
    for (const auto& c : pts) targets.emplace_back(c.target.x, c.target.y);
    std::sort(targets.begin(), targets.end());
    const auto distinct = static_cast<std::size_t>(std::unique(targets.begin(), targets.end()) - targets.begin());
    if (distinct < terms) {
      throw std::invalid_argument(std::string(kind) + " needs at least " + std::to_string(terms) +
                                  " distinct targets; got " + std::to_string(distinct) +
                                  " distinct (more samples of a target do not add information)");
    }
  }
  ModelFit out;
  out.model = fit_once(kind, pts);
  const bool robust = kind != "bilinear-grid" &&
                      (options.robust == FitOptions::Robust::On ||
                       (options.robust == FitOptions::Robust::Auto && kind == "poly2"));
  if (!robust || pts.empty()) return out;
  if (!(options.k > 0) || options.max_rounds < 1) throw std::invalid_argument("robust fit: k must be > 0 and max_rounds >= 1");

  // Residual floor: a model that fits (nearly) exactly must not reject points for rounding noise.
  double extent = 0;
  for (const auto& c : pts) extent = std::max({extent, std::abs(c.target.x), std::abs(c.target.y)});
  const double floor = 1e-9 * std::max(extent, 1.0);
  const std::size_t keep_at_least = std::max(parameters_of(kind), (pts.size() + 1) / 2);
  std::vector<Correspondence> kept(pts.begin(), pts.end());
  for (int round = 0; round < options.max_rounds; ++round) {
    std::vector<double> residual(pts.size());
    for (std::size_t i = 0; i < pts.size(); ++i) {
      const Point p = out.model->apply(pts[i].raw);
      residual[i] = std::hypot(p.x - pts[i].target.x, p.y - pts[i].target.y);
    }
    // Sigma from the residuals of all correspondences against the current model (the rejected ones
    // are re-admitted when the model moves towards them).
    const double sigma = std::max(median_of(residual) / 1.1774, floor);
    std::vector<Correspondence> next;
    for (std::size_t i = 0; i < pts.size(); ++i) {
      if (std::isfinite(residual[i]) && residual[i] <= options.k * sigma) next.push_back(pts[i]);
    }
    if (next.size() < keep_at_least || next.size() == kept.size()) {
      if (next.size() == kept.size()) out.outliers_rejected = pts.size() - kept.size();
      break;
    }
    std::unique_ptr<CalibrationModel> refit;
    try {
      refit = fit_once(kind, next);
    } catch (const std::invalid_argument&) {
      break;  // the inliers alone do not determine the model: keep the last good fit
    }
    out.model = std::move(refit);
    kept = std::move(next);
    out.outliers_rejected = pts.size() - kept.size();
  }
  return out;
}

std::unique_ptr<CalibrationModel> model_from_json(const json& j, const std::string& where) {
  const json& k = member(j, where, "kind");
  if (!k.is_string()) bad(where, "kind", "must be a string");
  const std::string kind = k.get<std::string>();
  if (kind == "poly2") return Poly2Model::from_json(j, where);
  if (kind == "affine") return AffineModel::from_json(j, where);
  if (kind == "homography") return HomographyModel::from_json(j, where);
  if (kind == "bilinear-grid") return GridModel::from_json(j, where);
  bad(where, "kind", "is '" + kind + "', not a known model (" + kinds_list() + ")");
}

json Calibration::to_json() const {
  json j{{"format", "fovea-calibration"},
         {"version", kCalibrationFileVersion},
         {"model", model->to_json()},
         {"points_used", points_used},
         {"rms_residual", rms_residual},
         {"condition", std::isfinite(condition) ? json(condition) : json(nullptr)},
         {"created", created}};
  j["input"] = input;
  if (!eye.empty()) j["eye"] = eye;
  j["target_space"] = target_space;
  j["outliers_rejected"] = outliers_rejected;
  if (on_top_of) j["on_top_of"] = on_top_of->to_json();
  if (display) j["display"] = calib::to_json(*display);
  if (!validation.is_null()) j["validation"] = validation;
  return j;
}

Point Calibration::apply(Point raw) const {
  const Point out = model->apply(on_top_of ? on_top_of->apply(raw) : raw);
  if (target_space == kTargetFickDegrees) {
    if (!display) return {std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::quiet_NaN()};
    return fick_deg_to_px(*display, out);
  }
  return out;
}

std::optional<double> Calibration::validated_accuracy_deg() const {
  if (!validation.is_object()) return std::nullopt;
  const auto it = validation.find("accuracy_deg");
  if (it == validation.end() || !it->is_number()) return std::nullopt;
  const double a = it->get<double>();
  return std::isfinite(a) ? std::optional<double>(a) : std::nullopt;
}

std::string Calibration::describe() const {
  std::ostringstream s;
  s << (model ? model->kind() : "?");
  if (on_top_of) s << " on " << on_top_of->kind();
  s << " on " << input;
  if (!eye.empty()) s << " (" << eye << " eye)";
  s << ", " << points_used << " samples";
  if (const auto a = validated_accuracy_deg()) {
    s.setf(std::ios::fixed);
    s.precision(2);
    s << ", validated " << *a << " deg";
  } else {
    s << ", not validated";
  }
  return s.str();
}

std::string utc_now_iso8601() {
  const std::time_t now = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&now, &tm);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return buf;
}

Calibration fit_calibration(std::string_view kind, std::span<const Correspondence> pts, const Calibration* base,
                            const FitOptions& options, const Display* fick_display) {
  Calibration cal;
  std::vector<Correspondence> corrected;
  std::span<const Correspondence> use = pts;
  if (fick_display) {
    if (const std::string problem = check(*fick_display); !problem.empty()) throw std::invalid_argument(problem);
    if (base && base->target_space != kTargetPixels) {
      throw std::invalid_argument("a model in Fick angles cannot be stacked on one that is not in pixels");
    }
    corrected.reserve(pts.size());
    for (const auto& c : pts) corrected.push_back({c.raw, px_to_fick_deg(*fick_display, c.target)});
    use = corrected;
    cal.target_space = kTargetFickDegrees;
    cal.display = *fick_display;
  }
  if (base) {
    if (base->on_top_of) {
      throw std::invalid_argument("the base calibration is itself a " + base->model->kind() + " on top of a " +
                                  base->on_top_of->kind() + "; stacking more than two models is not supported");
    }
    if (base->target_space != kTargetPixels) {
      throw std::invalid_argument("the base calibration's output is in " + base->target_space +
                                  "; a model can only be stacked on one whose output is in pixels");
    }
    std::vector<Correspondence> on_base;
    on_base.reserve(use.size());
    for (const auto& c : use) on_base.push_back({base->model->apply(c.raw), c.target});
    corrected = std::move(on_base);
    use = corrected;
    cal.on_top_of = base->model->clone();
    if (!fick_display) cal.display = base->display;
    cal.input = base->input;
    cal.eye = base->eye;
  }
  ModelFit fit = fit_model(kind, use, options);
  cal.model = std::move(fit.model);
  cal.outliers_rejected = fit.outliers_rejected;
  const FitStats s = cal.model->stats();
  cal.points_used = s.points;
  cal.rms_residual = s.rms_residual;  // of model(base(raw)) against the targets: the whole chain
  cal.condition = s.condition;
  cal.created = utc_now_iso8601();
  return cal;
}

void save_calibration(const Calibration& cal, const std::filesystem::path& path, bool overwrite) {
  namespace fs = std::filesystem;
  if (!cal.model) throw std::invalid_argument("save_calibration: no model");
  std::error_code ec;
  if (!overwrite && fs::exists(path, ec)) {
    throw std::runtime_error(path.string() + ": exists; refusing to overwrite it (use --force)");
  }
  fs::path tmp = path;
  tmp += ".tmp-" + std::to_string(::getpid());
  {
    std::ofstream out(tmp, std::ios::trunc);
    if (!out) throw std::runtime_error(tmp.string() + ": cannot create: " + std::strerror(errno));
    out << cal.to_json().dump(2) << '\n';
    out.flush();
    if (!out) {
      fs::remove(tmp, ec);
      throw std::runtime_error(tmp.string() + ": write failed");
    }
  }
  if (overwrite) {
    fs::rename(tmp, path, ec);
  } else {
    // A hard link fails if `path` appeared meanwhile: no clobbering, even racing another writer.
    fs::create_hard_link(tmp, path, ec);
    std::error_code ignored;
    fs::remove(tmp, ignored);
  }
  if (ec) {
    fs::remove(tmp, ec);
    throw std::runtime_error(path.string() + ": cannot write: " + ec.message());
  }
}

namespace {

std::string read_text(const std::filesystem::path& path, const std::string& name) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error(name + ": cannot open: " + std::strerror(errno));
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// A calibration file nests three levels; the daemon parses one a control request names, so a
// hostile file nested 100,000 deep is refused while parsing rather than built (issue 23 item 7).
constexpr int kMaxJsonDepth = 32;

json parse_json(const std::string& text, const std::string& name) {
  json j;
  bool too_deep = false;
  try {
    j = json::parse(text, [&](int depth, json::parse_event_t event, json&) {
      if ((event == json::parse_event_t::object_start || event == json::parse_event_t::array_start) &&
          depth >= kMaxJsonDepth) {
        too_deep = true;
        throw std::runtime_error("too deep");
      }
      return true;
    });
  } catch (const json::parse_error& e) {
    throw std::runtime_error(name + ": not valid JSON: " + e.what());
  } catch (const std::runtime_error&) {
    if (!too_deep) throw;
    throw std::runtime_error(name + ": nested deeper than " + std::to_string(kMaxJsonDepth) +
                             " levels; not a fovea calibration file");
  }
  return j;
}

// The file says it is a fovea calibration, of a version this build reads.
void check_format_and_version(const json& j, const std::string& name) {
  if (!j.is_object()) throw std::invalid_argument(name + ": must be a JSON object (a fovea calibration file)");
  const json& format = member(j, name, "format");
  if (!format.is_string() || format.get<std::string>() != "fovea-calibration") {
    bad(name, "format", "must be \"fovea-calibration\" (this is not a fovea calibration file)");
  }
  const json& version = member(j, name, "version");
  if (!version.is_number_integer()) bad(name, "version", "must be an integer");
  const auto v = version.get<long long>();
  if (v > kCalibrationFileVersion) {
    throw std::invalid_argument(name + ": written by a newer fovea (version " + std::to_string(v) +
                                "); this build reads version " + std::to_string(kCalibrationFileVersion));
  }
  if (v < 1) bad(name, "version", "is " + std::to_string(v) + "; versions start at 1");
}

// The model(s) and the fit's figures, which every version has, and the display.
void read_fit(const json& j, const std::string& name, Calibration& cal) {
  cal.model = model_from_json(member(j, name, "model"), name + ": model");
  if (j.contains("on_top_of")) cal.on_top_of = model_from_json(j["on_top_of"], name + ": on_top_of");
  const json& pu = member(j, name, "points_used");
  if (!pu.is_number_unsigned()) bad(name, "points_used", "must be a non-negative integer");
  cal.points_used = pu.get<std::size_t>();
  cal.rms_residual = number(member(j, name, "rms_residual"), name, "rms_residual");
  const json& cond = member(j, name, "condition");
  cal.condition = cond.is_null() ? std::numeric_limits<double>::quiet_NaN() : number(cond, name, "condition");
  const json& created = member(j, name, "created");
  if (!created.is_string()) bad(name, "created", "must be an ISO-8601 string");
  cal.created = created.get<std::string>();
  if (j.contains("display")) cal.display = display_from_json(j["display"], name + ": display");
}

// What the model maps from and to: the input, the eye and the target space (optional fields).
void read_spaces(const json& j, const std::string& name, Calibration& cal) {
  // Files written before "input" existed were fitted from CSV on screen points.
  if (j.contains("input")) {
    const json& input = j["input"];
    if (!input.is_string() ||
        (input.get<std::string>() != kInputScreen && input.get<std::string>() != kInputPupilGlint)) {
      bad(name, "input", "must be \"screen\" or \"pupil-glint\"");
    }
    cal.input = input.get<std::string>();
  }
  if (j.contains("eye")) {
    const json& e = j["eye"];
    if (!e.is_string() || (e.get<std::string>() != "left" && e.get<std::string>() != "right")) {
      bad(name, "eye", "must be \"left\" or \"right\"");
    }
    cal.eye = e.get<std::string>();
  }
  if (j.contains("target_space")) {
    const json& t = j["target_space"];
    if (!t.is_string() || (t.get<std::string>() != kTargetPixels && t.get<std::string>() != kTargetFickDegrees)) {
      bad(name, "target_space", "must be \"px\" or \"fick-deg\"");
    }
    cal.target_space = t.get<std::string>();
    if (cal.target_space == kTargetFickDegrees && !cal.display) {
      bad(name, "display", "is required when target_space is \"fick-deg\"");
    }
  }
}

// The robust fit's rejections and the validation summary (optional fields).
void read_outliers_and_validation(const json& j, const std::string& name, Calibration& cal) {
  if (j.contains("outliers_rejected")) {
    if (!j["outliers_rejected"].is_number_unsigned()) bad(name, "outliers_rejected", "must be a non-negative integer");
    cal.outliers_rejected = j["outliers_rejected"].get<std::size_t>();
  }
  if (j.contains("validation")) {
    if (!j["validation"].is_object()) bad(name, "validation", "must be an object");
    cal.validation = j["validation"];
    if (cal.validation.contains("accuracy_deg") && !cal.validation["accuracy_deg"].is_null()) {
      const double a = number(cal.validation["accuracy_deg"], name + ": validation", "accuracy_deg");
      if (a < 0) bad(name + ": validation", "accuracy_deg", "must be >= 0");
    }
  }
}

}  // namespace

Calibration load_calibration(const std::filesystem::path& path) {
  const std::string name = path.string();
  return parse_calibration(read_text(path, name), name);
}

Calibration parse_calibration(const std::string& text, const std::string& name) {
  const json j = parse_json(text, name);
  try {
    check_format_and_version(j, name);
    Calibration cal;
    read_fit(j, name, cal);
    read_spaces(j, name, cal);
    read_outliers_and_validation(j, name, cal);
    return cal;
  } catch (const std::invalid_argument& e) {
    throw std::runtime_error(e.what());
  }
}

}  // namespace fovea::calib
