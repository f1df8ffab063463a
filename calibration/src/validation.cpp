// SPDX-License-Identifier: Apache-2.0
#include "fovea/calib/validation.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <stdexcept>
#include <utility>

namespace fovea::calib {

namespace {

bool finite(Point p) { return std::isfinite(p.x) && std::isfinite(p.y); }

// A finite point, pulled in to kFarPx from the screen centre (same direction) when beyond it.
Point near_enough(Point p, const Display& d) {
  const double cx = d.width_px / 2, cy = d.height_px / 2;
  const double dx = p.x - cx, dy = p.y - cy;
  const double m = std::max(std::abs(dx), std::abs(dy));
  if (m <= kFarPx) return p;
  // Scale by the larger component first: hypot of two values near DBL_MAX would overflow.
  const double r = m * std::hypot(dx / m, dy / m);
  return {cx + dx / r * kFarPx, cy + dy / r * kFarPx};
}

// Statistics of one target's usable samples `pts` (time order, already near_enough).
ErrorStats stats_of(const std::vector<Point>& pts, std::size_t lost, Point target, const Display& d) {
  ErrorStats s;
  s.samples = pts.size();
  s.lost = lost;
  if (pts.empty()) return s;
  const double n = static_cast<double>(pts.size());
  const double kx = d.width_mm / d.width_px, ky = d.height_mm / d.height_px;
  Point mean;
  double sum_deg = 0, sum_mm = 0;
  s.min_deg = std::numeric_limits<double>::infinity();
  s.max_deg = 0;
  for (const Point& p : pts) {
    const double e = angle_between_deg(d, target, p);
    sum_deg += e;
    sum_mm += std::hypot((p.x - target.x) * kx, (p.y - target.y) * ky);
    s.min_deg = std::min(s.min_deg, e);
    s.max_deg = std::max(s.max_deg, e);
    mean.x += p.x / n;
    mean.y += p.y / n;
  }
  s.accuracy_deg = sum_deg / n;
  s.accuracy_mm = sum_mm / n;
  s.mean_error_px = {mean.x - target.x, mean.y - target.y};
  double sum_sq_pairs = 0, sum_sq_mean = 0;
  for (std::size_t i = 0; i < pts.size(); ++i) {
    const double to_mean = angle_between_deg(d, pts[i], mean);
    sum_sq_mean += to_mean * to_mean;
    if (i > 0) {
      const double step = angle_between_deg(d, pts[i - 1], pts[i]);
      sum_sq_pairs += step * step;
    }
  }
  s.precision_rms_deg = pts.size() > 1 ? std::sqrt(sum_sq_pairs / (n - 1)) : 0.0;
  s.precision_std_deg = std::sqrt(sum_sq_mean / n);
  return s;
}

// Overall figures from per-target ones (see ValidationResult::after).
ErrorStats overall_of(const std::vector<const ErrorStats*>& per_target) {
  ErrorStats o;
  std::size_t with_data = 0;
  o.min_deg = std::numeric_limits<double>::infinity();
  for (const ErrorStats* s : per_target) {
    o.samples += s->samples;
    o.lost += s->lost;
    if (!s->has_data()) continue;
    ++with_data;
    o.accuracy_deg += s->accuracy_deg;
    o.accuracy_mm += s->accuracy_mm;
    o.precision_rms_deg += s->precision_rms_deg;
    o.precision_std_deg += s->precision_std_deg;
    o.mean_error_px.x += s->mean_error_px.x;
    o.mean_error_px.y += s->mean_error_px.y;
    o.min_deg = std::min(o.min_deg, s->min_deg);
    o.max_deg = std::max(o.max_deg, s->max_deg);
  }
  if (with_data == 0) {
    const std::size_t samples = o.samples, lost = o.lost;
    o = ErrorStats{};
    o.samples = samples;
    o.lost = lost;
    return o;
  }
  const double k = static_cast<double>(with_data);
  o.accuracy_deg /= k;
  o.accuracy_mm /= k;
  o.precision_rms_deg /= k;
  o.precision_std_deg /= k;
  o.mean_error_px = {o.mean_error_px.x / k, o.mean_error_px.y / k};
  return o;
}

std::string fixed(double v, int decimals) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", decimals, v);
  return buf;
}

// The figure columns of one ErrorStats, as text ("-" when absent).
std::vector<std::string> stat_cells(const ErrorStats& s) {
  std::vector<std::string> c{std::to_string(s.samples), std::to_string(s.lost)};
  if (!s.has_data()) {
    c.insert(c.end(), 6, "-");
    return c;
  }
  for (const auto& [v, dec] : {std::pair{s.accuracy_deg, 3}, std::pair{s.accuracy_mm, 2},
                               std::pair{s.precision_rms_deg, 3}, std::pair{s.precision_std_deg, 3},
                               std::pair{s.min_deg, 3}, std::pair{s.max_deg, 3}}) {
    c.push_back(fixed(v, dec));
  }
  return c;
}

}  // namespace

ValidationResult validate(std::span<const ValidationSample> samples, const Display& display) {
  if (const std::string err = check(display); !err.empty()) throw std::invalid_argument("validate: display " + err);
  if (samples.empty()) throw std::invalid_argument("validate: no samples");
  bool all_before = true;
  std::map<std::pair<double, double>, std::size_t> index;
  struct Group {
    Point target;
    std::vector<Point> after, before;
    std::size_t after_lost = 0, before_lost = 0;
  };
  std::vector<Group> groups;
  for (std::size_t i = 0; i < samples.size(); ++i) {
    const ValidationSample& s = samples[i];
    if (!finite(s.target_px)) {
      throw std::invalid_argument("validate: sample " + std::to_string(i + 1) + ": target (" +
                                  std::to_string(s.target_px.x) + ", " + std::to_string(s.target_px.y) +
                                  ") is not finite");
    }
    // +0.0 and -0.0 are the same target (std::map compares with <).
    const auto [it, added] = index.try_emplace({s.target_px.x, s.target_px.y}, groups.size());
    if (added) groups.push_back({s.target_px, {}, {}, 0, 0});
    Group& g = groups[it->second];
    if (finite(s.measured_px)) {
      g.after.push_back(near_enough(s.measured_px, display));
    } else {
      ++g.after_lost;
    }
    if (!s.before_px) {
      all_before = false;
    } else if (finite(*s.before_px)) {
      g.before.push_back(near_enough(*s.before_px, display));
    } else {
      ++g.before_lost;
    }
  }
  ValidationResult r;
  for (const Group& g : groups) {
    TargetValidation t{g.target, stats_of(g.after, g.after_lost, g.target, display), std::nullopt};
    if (all_before) t.before = stats_of(g.before, g.before_lost, g.target, display);
    r.targets.push_back(t);
  }
  std::vector<const ErrorStats*> after, before;
  for (const auto& t : r.targets) {
    after.push_back(&t.after);
    if (t.before) before.push_back(&*t.before);
  }
  r.after = overall_of(after);
  if (all_before) r.before = overall_of(before);
  if (!r.after.has_data()) {
    throw std::invalid_argument("validate: no usable sample: all " + std::to_string(samples.size()) +
                                " measured points are lost (not finite)");
  }
  return r;
}

namespace {

// The table's columns: the groups (target, [before], after) with their column counts, and every column's name.
struct TableColumns {
  std::vector<std::pair<std::string, std::size_t>> groups;
  std::vector<std::string> names;
};

TableColumns table_columns(bool with_before) {
  const std::vector<std::string> stat_names{"n",       "lost",    "acc deg", "acc mm",
                                            "RMS deg", "STD deg", "min deg", "max deg"};
  std::vector<std::pair<std::string, std::size_t>> groups{{"target px", 2}};
  if (with_before) groups.push_back({"before", stat_names.size()});
  groups.push_back({with_before ? "after" : "accuracy and precision", stat_names.size()});
  std::vector<std::string> names{"x", "y"};
  if (with_before) names.insert(names.end(), stat_names.begin(), stat_names.end());
  names.insert(names.end(), stat_names.begin(), stat_names.end());
  return {std::move(groups), std::move(names)};
}

void append_stat_cells(std::vector<std::string>& row, const ErrorStats& s) {
  const auto c = stat_cells(s);
  row.insert(row.end(), c.begin(), c.end());
}

// The table's cells: a row per target, then the overall row.
struct TableRows {
  std::vector<std::vector<std::string>> targets;
  std::vector<std::string> overall;
};

TableRows table_rows(const ValidationResult& result, bool with_before) {
  TableRows rows;
  for (const auto& t : result.targets) {
    std::vector<std::string> row{fixed(t.target_px.x, 1), fixed(t.target_px.y, 1)};
    if (with_before) append_stat_cells(row, t.before ? *t.before : ErrorStats{});
    append_stat_cells(row, t.after);
    rows.targets.push_back(std::move(row));
  }
  rows.overall = {"overall", ""};
  if (with_before) append_stat_cells(rows.overall, *result.before);
  append_stat_cells(rows.overall, result.after);
  return rows;
}

// Width of the columns [first, first + count) with their separators.
std::size_t group_width(const std::vector<std::size_t>& width, std::size_t first, std::size_t count) {
  std::size_t w = 0;
  for (std::size_t k = first; k < first + count; ++k) w += width[k] + (k > first ? 2 : 0);
  return w;
}

// Each column as wide as its widest cell.
std::vector<std::size_t> column_widths(const TableColumns& columns, const TableRows& rows) {
  const std::vector<std::string>& names = columns.names;
  std::vector<std::size_t> width(names.size());
  for (std::size_t k = 0; k < names.size(); ++k) {
    width[k] = names[k].size();
    for (const auto& row : rows.targets) width[k] = std::max(width[k], row[k].size());
    width[k] = std::max(width[k], rows.overall[k].size());
  }
  // Widen a group's last column when its label is longer than the group.
  std::size_t first = 0;
  for (const auto& [label, count] : columns.groups) {
    const std::size_t w = group_width(width, first, count);
    if (label.size() > w) width[first + count - 1] += label.size() - w;
    first += count;
  }
  return width;
}

// One line of cells under their columns, groups split by " | ", with no trailing spaces.
std::string table_line(const TableColumns& columns, const std::vector<std::size_t>& width,
                       const std::vector<std::string>& cells) {
  const auto& groups = columns.groups;
  std::string out;
  std::size_t k = 0;
  for (std::size_t g = 0; g < groups.size(); ++g) {
    if (g > 0) out += " | ";
    for (std::size_t i = 0; i < groups[g].second; ++i, ++k) {
      if (i > 0) out += "  ";
      // "overall" is left-aligned; everything else right-aligned.
      const bool left = k == 0 && cells[k] == "overall";
      const std::string pad(width[k] - cells[k].size(), ' ');
      out += left ? cells[k] + pad : pad + cells[k];
    }
  }
  while (!out.empty() && out.back() == ' ') out.pop_back();
  return out + "\n";
}

// The group labels, each centred over its columns.
std::string table_header(const TableColumns& columns, const std::vector<std::size_t>& width) {
  const auto& groups = columns.groups;
  std::string header;
  std::size_t first = 0;
  for (std::size_t g = 0; g < groups.size(); ++g) {
    const std::size_t w = group_width(width, first, groups[g].second);
    const std::string& label = groups[g].first;
    const std::size_t left = (w - label.size()) / 2;
    if (g > 0) header += " | ";
    header += std::string(left, ' ') + label + std::string(w - label.size() - left, ' ');
    first += groups[g].second;
  }
  while (!header.empty() && header.back() == ' ') header.pop_back();
  return header + "\n";
}

// The legend under the table: what the figures are, and how many targets the overall row averages.
std::string table_notes(const ValidationResult& result) {
  std::size_t with_data = 0;
  for (const auto& t : result.targets) if (t.after.has_data()) ++with_data;
  return "accuracy: mean angle between sample and target (deg) and on-screen distance (mm); precision: RMS of\n"
         "successive sample-to-sample angles and STD (RMS angle to the samples' mean); min/max: sample errors.\n"
         "overall: mean over the " +
         std::to_string(with_data) + " target(s) with data, each weighing the same" +
         (with_data < result.targets.size()
              ? " (" + std::to_string(result.targets.size() - with_data) + " target(s) had only lost samples)"
              : std::string()) +
         "; min/max over all samples.\n";
}

}  // namespace

std::string format_table(const ValidationResult& result) {
  const bool with_before = result.before.has_value();
  const TableColumns columns = table_columns(with_before);
  const TableRows rows = table_rows(result, with_before);
  const std::vector<std::size_t> width = column_widths(columns, rows);
  std::string out = table_header(columns, width) + table_line(columns, width, columns.names);
  std::string rule = table_line(columns, width, columns.names);
  for (char& ch : rule) {
    if (ch != '|' && ch != '\n') ch = '-';
  }
  out += rule;
  for (const auto& row : rows.targets) out += table_line(columns, width, row);
  out += rule + table_line(columns, width, rows.overall);
  out += table_notes(result);
  return out;
}

nlohmann::json to_json(const ErrorStats& s) {
  nlohmann::json j{{"samples", s.samples}, {"lost", s.lost}};
  const auto put = [&](const char* key, double v) { j[key] = s.has_data() ? nlohmann::json(v) : nlohmann::json(nullptr); };
  put("accuracy_deg", s.accuracy_deg);
  put("accuracy_mm", s.accuracy_mm);
  put("precision_rms_deg", s.precision_rms_deg);
  put("precision_std_deg", s.precision_std_deg);
  put("min_deg", s.min_deg);
  put("max_deg", s.max_deg);
  j["mean_error_px"] =
      s.has_data() ? nlohmann::json::array({s.mean_error_px.x, s.mean_error_px.y}) : nlohmann::json(nullptr);
  return j;
}

nlohmann::json to_json(const ValidationResult& r) {
  nlohmann::json targets = nlohmann::json::array();
  for (const auto& t : r.targets) {
    targets.push_back({{"target_px", {t.target_px.x, t.target_px.y}},
                       {"after", to_json(t.after)},
                       {"before", t.before ? to_json(*t.before) : nlohmann::json(nullptr)}});
  }
  return {{"targets", targets},
          {"overall", {{"after", to_json(r.after)}, {"before", r.before ? to_json(*r.before) : nlohmann::json(nullptr)}}}};
}

}  // namespace fovea::calib
