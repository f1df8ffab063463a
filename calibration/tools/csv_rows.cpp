// SPDX-License-Identifier: Apache-2.0
#include "csv_rows.h"

#include <charconv>
#include <cmath>
#include <fstream>
#include <stdexcept>
#include <system_error>

namespace fovea::calib::csv {

namespace {

std::string trim(std::string s) {
  while (!s.empty() && (s.back() == '\r' || s.back() == ' ' || s.back() == '\t')) s.pop_back();
  std::size_t b = 0;
  while (b < s.size() && (s[b] == ' ' || s[b] == '\t')) ++b;
  return s.substr(b);
}

std::vector<std::string> split(const std::string& line) {
  std::vector<std::string> out;
  std::size_t start = 0;
  for (;;) {
    const std::size_t comma = line.find(',', start);
    out.push_back(trim(line.substr(start, comma == std::string::npos ? std::string::npos : comma - start)));
    if (comma == std::string::npos) return out;
    start = comma + 1;
  }
}

}  // namespace

std::vector<Row> read_csv(const std::string& path, const std::vector<std::string>& header, bool allow_nan,
                          std::size_t nan_from) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error(path + ": cannot open");
  std::string line;
  std::size_t no = 0;
  std::vector<Row> rows;
  bool have_header = false;
  std::string want;
  for (const auto& h : header) want += (want.empty() ? "" : ",") + h;
  while (std::getline(in, line)) {
    ++no;
    line = trim(line);
    if (line.empty() || line[0] == '#') continue;
    const auto fields = split(line);
    if (!have_header) {
      if (fields != header) {
        throw std::runtime_error(path + ":" + std::to_string(no) + ": header must be '" + want + "', not '" + line + "'");
      }
      have_header = true;
      continue;
    }
    if (fields.size() != header.size()) {
      throw std::runtime_error(path + ":" + std::to_string(no) + ": " + std::to_string(fields.size()) +
                               " field(s); expected " + std::to_string(header.size()) + " (" + want + ")");
    }
    Row r{no, fields, {}};
    for (std::size_t c = 0; c < fields.size(); ++c) {
      const std::string& f = fields[c];
      double v = 0;
      const auto [end, ec] = std::from_chars(f.data(), f.data() + f.size(), v);
      const bool parsed = !f.empty() && ec == std::errc() && end == f.data() + f.size();
      const bool nan_ok = allow_nan && c >= nan_from && std::isnan(v);
      if (!parsed || (!std::isfinite(v) && !nan_ok)) {
        throw std::runtime_error(path + ":" + std::to_string(no) + ": column " + std::to_string(c + 1) + " (" +
                                 header[c] + "): '" + f + "' is not a " + (parsed ? "finite " : "") + "number");
      }
      r.values.push_back(v);
    }
    rows.push_back(std::move(r));
  }
  if (!have_header) throw std::runtime_error(path + ": empty; expected the header '" + want + "'");
  return rows;
}

}  // namespace fovea::calib::csv
