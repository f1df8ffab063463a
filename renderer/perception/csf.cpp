// SPDX-License-Identifier: Apache-2.0
#include "perception/csf.h"

#include <cmath>
#include <limits>

namespace fovea::render::perception {

namespace {

bool finite_positive(double v) { return std::isfinite(v) && v > 0; }

std::string field_error(const char* prefix, const char* field, double value, const char* allowed) {
  return std::string(prefix) + field + " = " + std::to_string(value) + " (allowed " + allowed + ")";
}

}  // namespace

std::string validate(const GeislerPerry& m, const char* prefix) {
  if (!(std::isfinite(m.ct0) && m.ct0 > 0 && m.ct0 < 1)) return field_error(prefix, "ct0", m.ct0, "(0, 1)");
  if (!finite_positive(m.alpha)) return field_error(prefix, "alpha", m.alpha, "finite > 0");
  if (!finite_positive(m.e2_deg)) return field_error(prefix, "e2_deg", m.e2_deg, "finite > 0 degrees");
  return {};
}

double contrast_threshold(double frequency_cpd, double eccentricity_deg, const GeislerPerry& m) {
  const double e = std::abs(eccentricity_deg);
  return m.ct0 * std::exp(m.alpha * frequency_cpd * (e + m.e2_deg) / m.e2_deg);  // Murphy 2007, eq. 4.1
}

double cutoff_eccentricity_deg(double frequency_cpd, const GeislerPerry& m) {
  if (!(frequency_cpd > 0)) return std::numeric_limits<double>::infinity();
  return m.e2_deg / (m.alpha * frequency_cpd) * std::log(1.0 / m.ct0) - m.e2_deg;  // Murphy 2007, eq. 4.2
}

double cutoff_frequency_cpd(double eccentricity_deg, const GeislerPerry& m) {
  const double e = std::abs(eccentricity_deg);
  return m.e2_deg * std::log(1.0 / m.ct0) / (m.alpha * (e + m.e2_deg));  // Murphy 2007, eq. 4.3
}

}  // namespace fovea::render::perception
