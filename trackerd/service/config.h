// SPDX-License-Identifier: Apache-2.0
#pragma once
// fovea-trackerd's configuration: a TOML file (deploy/trackerd.toml documents every key), overridden
// by command-line flags. Loading is strict: an unknown key, a value of the wrong type or out of range
// is an error that names the file, the line, the key and what is allowed.
#include <cstdint>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "fovea/protocol/display_geometry.h"
#include "fovea/protocol/server.h"

namespace fovea::trackerd::classify {
enum class PsoConvention : std::uint8_t;  // classify/classifier.h
}  // namespace fovea::trackerd::classify

namespace fovea::trackerd::service {

// The file the service unit passes with --config, and the one --check-config checks by default.
inline constexpr const char* kDefaultConfigPath = "/etc/fovea/trackerd.toml";

struct SourceConfig {
  std::string spec = "synthetic";  // a row of sources/source_table.cpp: synthetic | replay:FILE | gazepoint:HOST | ...
  double rate_hz = 0;              // synthetic 1..10000, synthetic-eye 1..1000 Hz; 0: the source's default (250 / 120)
  std::uint64_t seed = 1;          // synthetic, synthetic-eye: random seed
  double speed = 1.0;              // replay: speed factor, (0, 1000]
  bool loop = false;               // replay: start again at the end
  friend bool operator==(const SourceConfig&, const SourceConfig&) = default;
};

struct NetworkConfig {
  std::string listen = "127.0.0.1";
  std::uint16_t port = protocol::kDefaultPort;
  std::string multicast;  // GROUP:PORT, empty: none
  int multicast_ttl = 1;
  std::size_t max_subscribers = 256;
  std::uint32_t lease_ms = 5000;  // default lease for subscribers that do not ask for one
  // Control commands come through the local control socket (protocol/control_socket.h): "" its
  // default path for the port, "none" no local control. UDP control is authorised by source address
  // only, so it is off unless networks are listed here (every user on them is then an operator).
  std::string control_socket;
  // Where record-start may create recordings (service/control_paths.h); "" = the daemon's working
  // directory when it started (/var/lib/fovea for the service).
  std::string control_dir;
  // Where calibration-load may read a file (confined as record-start is, and never through a
  // symbolic link); "" = control_dir.
  std::string calibration_dir;
  // Ignored (a warning at start): control over UDP, authorised by source address alone, is gone
  // (issue 23). Still parsed and checked, so that configuration files written for earlier versions
  // (whose example allowed 127.0.0.0/8) start, with UDP control off.
  std::vector<protocol::Ipv4Cidr> control_allow;
  friend bool operator==(const NetworkConfig&, const NetworkConfig&) = default;
};

struct RecordConfig {
  std::string path;  // empty: do not record
  bool append = false;
  friend bool operator==(const RecordConfig&, const RecordConfig&) = default;
};

// [lsl]: the Lab Streaming Layer outlet (trackerd/lsl/lsl_outlet.h).
struct LslConfig {
  bool outlet = false;        // publish gaze and markers as LSL streams
  std::string name = "fovea";  // stream names "<name> gaze", "<name> markers"
  friend bool operator==(const LslConfig&, const LslConfig&) = default;
};

struct CalibrationConfig {
  std::string file;  // empty: none (identity)
  friend bool operator==(const CalibrationConfig&, const CalibrationConfig&) = default;
};

struct ClassifierConfig {
  std::string method;  // empty: the classify module's default; validated by that module
  std::string pso = "separate";  // separate | onset | none (the latter two gbt only): classify::PsoConvention
  double pursuit_weight = 0;     // gbt only: pursuit's weight in the smoothing's choice; 0 = the model's
  classify::PsoConvention pso_convention() const;  // pso as checked when read (the default if not one)
  friend bool operator==(const ClassifierConfig&, const ClassifierConfig&) = default;
};

// The eye pipeline (eye cameras, eye videos, the synthetic eye): trackerd/DEVICES.md.
struct EyeConfig {
  std::string side = "right";        // left | right: which eye the camera sees (the sample's EyeData it fills)
  std::string leds;                  // LED layout (preset "0".."5" or "x,y;x,y;..." mm); "" = the source's default
                                     // (synthetic-eye: preset 2; cameras and videos: unknown, glints unpaired)
  int pupil_downscale = 2;           // 1, 2 or 4: coarse pupil search on an image this much smaller
  bool pupil_roi = true;             // search near the last pupil first
  std::uint32_t synthetic_width = 320, synthetic_height = 240;  // synthetic-eye image size, 32..4096
  bool synthetic_hard = false;       // synthetic-eye: hard imaging conditions (noise, blur, lid, reflections)
  // synthetic-eye: "" (the random viewer) or "calibration:POINTS[:SEED[:VALIDATION]]" (a viewer who
  // follows the calibration fovea-calibrate run shows with those settings; calib::ScheduleOptions).
  std::string synthetic_script;
  std::string synthetic_head_offset_mm = "0,0,0";  // synthetic-eye: "x,y,z" mm, the head moved from the calibration position
  friend bool operator==(const EyeConfig&, const EyeConfig&) = default;
};
inline const std::vector<std::string> kEyeSides = {"left", "right"};

// A known tracker or eye camera (USB vendor:product), for device discovery and hotplug.
struct DeviceEntry {
  std::uint16_t vid = 0;
  std::uint16_t pid = 0;
  std::string kind;  // one of kDeviceKinds
  std::string name;
  friend bool operator==(const DeviceEntry&, const DeviceEntry&) = default;
};
inline const std::vector<std::string> kDeviceKinds = {"hid", "camera"};

struct DaemonConfig {
  std::string origin = "built-in defaults";  // the file it was read from, for messages
  SourceConfig source;
  std::optional<protocol::DisplayGeometry> display;  // unset: the source's own (synthetic default)
  NetworkConfig network;
  RecordConfig record;
  CalibrationConfig calibration;
  ClassifierConfig classifier;
  EyeConfig eye;
  LslConfig lsl;
  std::vector<DeviceEntry> devices;
  std::string log_level = "info";  // trace | debug | info | warn | error
};

// Every problem found in a configuration file, one per line, each "FILE:LINE: KEY: what is wrong;
// allowed: ...".
class ConfigError : public std::runtime_error {
 public:
  explicit ConfigError(std::vector<std::string> problems);
  const std::vector<std::string>& problems() const { return problems_; }

 private:
  std::vector<std::string> problems_;
};

// Reads and validates a configuration file. Relative paths in it (record.path, calibration.file)
// are resolved against the file's directory. Throws ConfigError.
DaemonConfig load_config(const std::string& path);
// The same, from text (`origin` names it in messages; relative paths resolve against `base_dir`).
DaemonConfig parse_config(const std::string& text, const std::string& origin, const std::string& base_dir = ".");

// "" when `method` is empty (the classify module's default) or a method this build knows; else
// what is wrong, with the known names. parse_config checks [classifier] method with it.
std::string check_classifier_method(const std::string& method);
// "" when pso (separate | none) goes with method, else what is wrong: only gbt labels without a PSO class.
std::string check_classifier_pso(const std::string& method, const std::string& pso);
// "" when pursuit_weight (0 = the model's, else 0.01..100) goes with method: only gbt weighs its classes.
std::string check_classifier_pursuit_weight(const std::string& method, double weight);

// Command-line values that override the file; unset members leave the file's value.
struct CliOverrides {
  std::optional<std::string> source;
  std::optional<double> rate_hz;
  std::optional<std::uint64_t> seed;
  std::optional<double> speed;
  std::optional<bool> loop;
  std::optional<protocol::DisplayGeometry> display;
  std::optional<std::string> listen;
  std::optional<std::uint16_t> port;
  std::optional<std::string> multicast;
  std::optional<int> multicast_ttl;
  std::optional<std::size_t> max_subscribers;
  std::optional<std::uint32_t> lease_ms;
  std::optional<std::string> control_socket;
  std::optional<std::string> control_dir;
  std::optional<std::string> record_path;
  std::optional<bool> record_append;
  std::optional<bool> lsl_outlet;
  std::optional<std::string> classifier_method;
  std::optional<std::string> classifier_pso;
  std::optional<double> classifier_pursuit_weight;
  std::optional<std::string> calibration_file;
  std::optional<std::string> log_level;
  std::optional<std::string> eye_side;
  std::optional<std::string> eye_leds;
  std::optional<int> pupil_downscale;
  std::optional<bool> pupil_roi;
  std::optional<std::pair<std::uint32_t, std::uint32_t>> synthetic_size;
  std::optional<bool> synthetic_hard;
  std::optional<std::string> synthetic_script;
  std::optional<std::string> synthetic_head_offset_mm;
};
void apply_overrides(DaemonConfig& config, const CliOverrides& cli);

// The configuration as a TOML document (what --check-config prints); load_config() reads it back
// to an equal configuration.
std::string to_toml(const DaemonConfig& config);

// Server options (listen address, multicast, limits, allow-list) for this configuration; throws
// std::invalid_argument when the listen address or multicast group cannot be parsed.
protocol::ServerOptions server_options(const DaemonConfig& config);

// What differs between two configurations, split by whether the running daemon can apply it.
struct ConfigChanges {
  std::vector<std::string> live;           // e.g. "network.lease_ms 5000 -> 2000"
  std::vector<std::string> needs_restart;  // e.g. "network.port 47800 -> 47801"
};
ConfigChanges diff(const DaemonConfig& running, const DaemonConfig& next);
// `next` with every setting that needs a restart taken from `running`: what a reload adopts.
DaemonConfig adopt_live(const DaemonConfig& running, const DaemonConfig& next);

}  // namespace fovea::trackerd::service
