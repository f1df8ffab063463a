#include "service/calibration_stage.h"

#include <cerrno>
#include <cstring>
#include <fstream>
#include <nlohmann/json.hpp>
#include <stdexcept>

namespace fovea::trackerd::service {

namespace {

class IdentityCalibration final : public CalibrationStage {
 public:
  explicit IdentityCalibration(std::string what) : what_(std::move(what)) {}
  std::string description() const override { return what_; }
  void apply(GazeItem&) const override {}

 private:
  std::string what_;
};

}  // namespace

std::unique_ptr<CalibrationStage> load_calibration_stage(const std::string& file) {
  if (file.empty()) return std::make_unique<IdentityCalibration>("none (identity)");
  std::ifstream in(file);
  if (!in) throw std::runtime_error("calibration file " + file + ": cannot read (" + std::strerror(errno) + ")");
  nlohmann::json doc;
  try {
    doc = nlohmann::json::parse(in);
  } catch (const std::exception& e) {
    throw std::runtime_error("calibration file " + file + ": not a JSON document (" + e.what() + ")");
  }
  // Seam for step 5: build the fitted calibration map from `doc` here.
  return std::make_unique<IdentityCalibration>(file + " (identity until the calibration map lands in step 5)");
}

}  // namespace fovea::trackerd::service
