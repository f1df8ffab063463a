// SPDX-License-Identifier: Apache-2.0
#pragma once
// Reading the CSV files of fovea-calibrate (POINTS.csv, raw streams): a fixed header, numbers only,
// errors that name the file, line and column.
#include <cstddef>
#include <string>
#include <vector>

namespace fovea::calib::csv {

struct Row {
  std::size_t line = 0;            // 1-based line in the file
  std::vector<std::string> text;   // the fields as written (trimmed)
  std::vector<double> values;      // the fields as numbers
};

// Reads a CSV with exactly `header`; every field a number (finite unless allow_nan; "nan" then
// allowed in the columns from `nan_from` on). Blank lines and lines starting with '#' are skipped.
// std::runtime_error naming the file, line and column.
std::vector<Row> read_csv(const std::string& path, const std::vector<std::string>& header, bool allow_nan,
                          std::size_t nan_from);

}  // namespace fovea::calib::csv
