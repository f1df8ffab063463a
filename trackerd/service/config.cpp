// SPDX-License-Identifier: Apache-2.0
#include "service/config.h"

#include <spdlog/fmt/fmt.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>
#include <sstream>
#include <toml++/toml.h>

#include "classify/classifier.h"
#include "fovea/protocol/bounded_file.h"
#include "lsl/lsl_outlet.h"
#include "sources/source_table.h"

namespace fovea::trackerd::service {

std::string check_classifier_method(const std::string& method) {
  // "source": the source's own labels and events pass through (the daemon's ClassifyStage).
  if (method.empty() || method == "source") return {};
  std::string names;
  for (const auto& m : classify::classifiers()) {
    if (m.name == method) return {};
    names += (names.empty() ? "" : ", ") + m.name;
  }
  return "unknown method \"" + protocol::escape_for_log(method, 40) + "\"; allowed: " + names +
         ", source (fovea-ctl classify --help describes the methods)";
}

classify::PsoConvention ClassifierConfig::pso_convention() const {
  return classify::pso_convention(pso).value_or(classify::PsoConvention::Separate);
}

std::string check_classifier_pso(const std::string& method, const std::string& pso) {
  const auto c = classify::pso_convention(pso);
  if (!c) return "\"" + protocol::escape_for_log(pso, 40) + "\" is no PSO convention; allowed: separate, onset, none";
  if (*c == classify::PsoConvention::Separate) return {};
  const std::string name = method.empty() ? classify::classifiers().front().name : method;
  const std::string what = "pso = \"" + pso + "\" is for method gbt only (";
  if (name == "source") return what + "source passes the source's own labels)";
  if (name != "gbt") return what + name + " finds its PSO by its own rule)";
  return {};
}

std::string check_classifier_pursuit_weight(const std::string& method, double weight) {
  if (weight == 0) return {};
  if (!(weight >= 0.01 && weight <= 100)) {
    return fmt::format("{} is out of range; allowed: 0 (the model's own) or a number in [0.01, 100]", weight);
  }
  const std::string name = method.empty() ? classify::classifiers().front().name : method;
  if (name != "gbt") {
    return "a pursuit weight is for method gbt only (" +
           (name == "source" ? std::string("source passes the source's own labels")
                             : name + "'s pursuit is a rule's, not a weighed choice") + ")";
  }
  return {};
}

namespace {

std::string join(const std::vector<std::string>& v, const char* sep = "\n") {
  std::string out;
  for (std::size_t i = 0; i < v.size(); ++i) out += (i ? sep : "") + v[i];
  return out;
}

const char* type_name(const toml::node& n) {
  switch (n.type()) {
    case toml::node_type::table:
      return "a table";
    case toml::node_type::array:
      return "an array";
    case toml::node_type::string:
      return "a string";
    case toml::node_type::integer:
      return "an integer";
    case toml::node_type::floating_point:
      return "a number";
    case toml::node_type::boolean:
      return "a boolean";
    case toml::node_type::date:
      return "a date";
    case toml::node_type::time:
      return "a time";
    case toml::node_type::date_time:
      return "a date-time";
    case toml::node_type::none:
      break;
  }
  return "nothing";
}

// Collects problems while walking the document; each one names file:line and the dotted key.
class Checker {
 public:
  Checker(std::string origin, std::filesystem::path base_dir)
      : origin_(std::move(origin)), base_(std::move(base_dir)) {}

  void problem(const toml::source_region& where, const std::string& key, const std::string& what) {
    problems_.push_back(fmt::format("{}:{}: {}: {}", origin_, where.begin.line, key, what));
  }
  const std::vector<std::string>& problems() const { return problems_; }

  // Reports keys of `t` that are not in `allowed`.
  void only(const toml::table& t, const std::string& prefix, const std::vector<std::string>& allowed) {
    for (auto&& [k, v] : t) {
      if (std::find(allowed.begin(), allowed.end(), std::string(k.str())) == allowed.end()) {
        problem(k.source().begin.line ? k.source() : v.source(), prefix + std::string(k.str()),
                "unknown key; allowed in " +
                    (prefix.empty() ? std::string("the top level") : "[" + prefix.substr(0, prefix.size() - 1) + "]") +
                    ": " + join(allowed, ", "));
      }
    }
  }

  const toml::table* table(const toml::table& parent, const char* name) {
    const toml::node* n = parent.get(name);
    if (n == nullptr) return nullptr;
    if (!n->is_table()) {
      problem(n->source(), name, std::string("must be a table ([") + name + "]), not " + type_name(*n));
      return nullptr;
    }
    return n->as_table();
  }

  void string(const toml::table& t, const std::string& prefix, const char* key, std::string& out,
              const char* allowed = "any text") {
    const toml::node* n = t.get(key);
    if (n == nullptr) return;
    if (!n->is_string()) {
      problem(n->source(), prefix + key,
              std::string("must be a string, not ") + type_name(*n) + "; allowed: " + allowed);
      return;
    }
    out = n->as_string()->get();
  }

  void boolean(const toml::table& t, const std::string& prefix, const char* key, bool& out) {
    const toml::node* n = t.get(key);
    if (n == nullptr) return;
    if (!n->is_boolean()) {
      problem(n->source(), prefix + key, std::string("must be true or false, not ") + type_name(*n));
      return;
    }
    out = n->as_boolean()->get();
  }

  template <typename T>
  void integer(const toml::table& t, const std::string& prefix, const char* key, T& out, std::int64_t lo,
               std::int64_t hi) {
    const toml::node* n = t.get(key);
    if (n == nullptr) return;
    const std::string allowed = fmt::format("an integer in {}..{}", lo, hi);
    if (!n->is_integer()) {
      problem(n->source(), prefix + key,
              std::string("must be an integer, not ") + type_name(*n) + "; allowed: " + allowed);
      return;
    }
    const std::int64_t v = n->as_integer()->get();
    if (v < lo || v > hi) {
      problem(n->source(), prefix + key, fmt::format("{} is out of range; allowed: {}", v, allowed));
      return;
    }
    out = static_cast<T>(v);
  }

  // A number (integer or float) with lo < v <= hi (lo_open) or lo <= v <= hi.
  void number(const toml::table& t, const std::string& prefix, const char* key, double& out, double lo, double hi,
              bool lo_open, const char* unit) {
    const toml::node* n = t.get(key);
    if (n == nullptr) return;
    const std::string allowed = fmt::format("a number in {}{}, {}] {}", lo_open ? "(" : "[", lo, hi, unit);
    double v = 0;
    if (n->is_integer()) {
      v = static_cast<double>(n->as_integer()->get());
    } else if (n->is_floating_point()) {
      v = n->as_floating_point()->get();
    } else {
      problem(n->source(), prefix + key,
              std::string("must be a number, not ") + type_name(*n) + "; allowed: " + allowed);
      return;
    }
    if (!std::isfinite(v) || (lo_open ? !(v > lo) : !(v >= lo)) || !(v <= hi)) {
      problem(n->source(), prefix + key, fmt::format("{} is out of range; allowed: {}", v, allowed));
      return;
    }
    out = v;
  }

  // Resolves a path from the file against the file's directory.
  std::string path(const std::string& p) const {
    if (p.empty() || std::filesystem::path(p).is_absolute()) return p;
    return (base_ / p).lexically_normal().string();
  }

  std::string origin_;

 private:
  std::filesystem::path base_;
  std::vector<std::string> problems_;
};

// USB ids: an integer (0x046d) or a string of 1-4 hex digits ("046d").
void usb_id(Checker& c, const toml::table& t, const std::string& prefix, const char* key, std::uint16_t& out) {
  const toml::node* n = t.get(key);
  const std::string allowed = "a 16-bit USB id: an integer 0..0xffff (e.g. 0x046d) or a string of 1-4 hex digits";
  if (n == nullptr) {
    c.problem(t.source(), prefix + key, "missing; every [[devices]] entry needs vid, pid, kind and name");
    return;
  }
  if (n->is_integer()) {
    const std::int64_t v = n->as_integer()->get();
    if (v < 0 || v > 0xFFFF) {
      c.problem(n->source(), prefix + key, fmt::format("{} is out of range; allowed: {}", v, allowed));
      return;
    }
    out = static_cast<std::uint16_t>(v);
    return;
  }
  if (n->is_string()) {
    const std::string s = n->as_string()->get();
    std::string digits = s.rfind("0x", 0) == 0 ? s.substr(2) : s;
    if (!digits.empty() && digits.size() <= 4 && std::all_of(digits.begin(), digits.end(), [](char ch) {
          return std::isxdigit(static_cast<unsigned char>(ch)) != 0;
        })) {
      out = static_cast<std::uint16_t>(std::stoul(digits, nullptr, 16));
      return;
    }
    c.problem(n->source(), prefix + key, "\"" + s + "\" is not a USB id; allowed: " + allowed);
    return;
  }
  c.problem(n->source(), prefix + key,
            std::string("must be an integer or a string, not ") + type_name(*n) + "; allowed: " + allowed);
}

void check_calibration_file(Checker& c, const toml::node& where, const std::string& path) {
  std::ifstream in(path);
  if (!in) {
    c.problem(where.source(), "calibration.file", path + ": cannot read (" + std::strerror(errno) + ")");
    return;
  }
  try {
    const nlohmann::json doc = nlohmann::json::parse(in);
    (void)doc;  // step 5 checks the calibration model's fields
  } catch (const std::exception& e) {
    c.problem(where.source(), "calibration.file", path + ": not a JSON document (" + e.what() + ")");
  }
}

const std::vector<std::string> kLogLevels = {"trace", "debug", "info", "warn", "error"};

// [source]: the spec (replay paths resolved against the file's directory), rate, seed, speed, loop.
void parse_source(Checker& c, const toml::table& t, SourceConfig& source) {
  c.only(t, "source.", {"spec", "rate", "seed", "speed", "loop"});
  const std::string kinds = source_kind_list();
  c.string(t, "source.", "spec", source.spec, kinds.c_str());
  if (source.spec.empty())
    c.problem(t.get("spec")->source(), "source.spec", "is empty; allowed: " + kinds);
  if (source.spec.rfind("replay:", 0) == 0 && source.spec.size() > 7) {
    source.spec = "replay:" + c.path(source.spec.substr(7));
  }
  c.number(t, "source.", "rate", source.rate_hz, 1, 10000, false, "Hz");
  c.integer(t, "source.", "seed", source.seed, 0, std::numeric_limits<std::int64_t>::max());
  c.number(t, "source.", "speed", source.speed, 0, 1000, true, "(1 = real time)");
  c.boolean(t, "source.", "loop", source.loop);
}

// [display]: all five keys or none; the geometry is kept only when complete and valid.
void parse_display(Checker& c, const toml::table& t, std::optional<protocol::DisplayGeometry>& display) {
  const std::vector<std::string> keys = {"width_px", "height_px", "width_mm", "height_mm", "distance_mm"};
  c.only(t, "display.", keys);
  bool complete = true;
  for (const auto& k : keys) {
    if (!t.contains(k)) {
      c.problem(t.source(), "display." + k, "missing; a [display] table needs all of " + join(keys, ", "));
      complete = false;
    }
  }
  protocol::DisplayGeometry g;
  double w = g.width_m * 1000, h = g.height_m * 1000, d = g.viewing_distance_m * 1000;
  c.integer(t, "display.", "width_px", g.width_px, 1, 65536);
  c.integer(t, "display.", "height_px", g.height_px, 1, 65536);
  c.number(t, "display.", "width_mm", w, 0, 100000, true, "mm");
  c.number(t, "display.", "height_mm", h, 0, 100000, true, "mm");
  c.number(t, "display.", "distance_mm", d, 0, 100000, true, "mm");
  g.width_m = w / 1000;
  g.height_m = h / 1000;
  g.viewing_distance_m = d / 1000;
  if (complete) {
    if (const std::string err = protocol::validate(g); !err.empty()) {
      c.problem(t.source(), "display", err);
    } else {
      display = g;
    }
  }
}

// network.control_allow: an array of A.B.C.D/N. Ignored since control over UDP is gone (NetworkConfig),
// but still checked so that a malformed one in an old file is named.
void parse_control_allow(Checker& c, const toml::node& node, std::vector<protocol::Ipv4Cidr>& control_allow) {
  const char* allowed =
      "an array of IPv4 networks A.B.C.D/N, e.g. [\"127.0.0.0/8\", \"192.168.1.0/24\"]; [] allows none";
  if (!node.is_array()) {
    c.problem(node.source(), "network.control_allow",
              std::string("must be an array, not ") + type_name(node) + "; allowed: " + allowed);
  } else {
    control_allow.clear();
    std::size_t i = 0;
    for (const toml::node& el : *node.as_array()) {
      const std::string key = fmt::format("network.control_allow[{}]", i++);
      if (!el.is_string()) {
        c.problem(el.source(), key, std::string("must be a string, not ") + type_name(el) + "; allowed: " + allowed);
        continue;
      }
      try {
        control_allow.push_back(protocol::parse_cidr(el.as_string()->get()));
      } catch (const std::exception& e) {
        c.problem(el.source(), key, e.what());
      }
    }
  }
}

// [network]: listen address and port, multicast group, subscriber limits, the control allow-list.
void parse_network(Checker& c, const toml::table& t, NetworkConfig& n) {
  c.only(t, "network.",
         {"listen", "port", "multicast", "multicast_ttl", "max_subscribers", "lease_ms", "control_socket",
          "control_dir", "calibration_dir", "control_allow"});
  c.string(t, "network.", "listen", n.listen, "a local IPv4 address, e.g. 127.0.0.1 or 0.0.0.0");
  if (const auto* node = t.get("listen"); node != nullptr && node->is_string()) {
    try {
      (void)protocol::parse_endpoint(n.listen, n.port);
    } catch (const std::exception& e) {
      c.problem(node->source(), "network.listen",
                std::string(e.what()) + "; allowed: a local IPv4 address, e.g. 127.0.0.1 or 0.0.0.0");
    }
  }
  c.integer(t, "network.", "port", n.port, 1, 65535);
  c.string(t, "network.", "multicast", n.multicast, "GROUP:PORT with GROUP in 224.0.0.0/4, or \"\" for none");
  if (const auto* node = t.get("multicast"); node != nullptr && node->is_string() && !n.multicast.empty()) {
    try {
      (void)protocol::parse_multicast(n.multicast);
    } catch (const std::exception& e) {
      c.problem(node->source(), "network.multicast", e.what());
    }
  }
  c.integer(t, "network.", "multicast_ttl", n.multicast_ttl, 0, 255);
  c.integer(t, "network.", "max_subscribers", n.max_subscribers, 1, 65536);
  c.integer(t, "network.", "lease_ms", n.lease_ms, 200, 60000);
  c.string(t, "network.", "control_socket", n.control_socket,
           "the control socket's path, \"\" for the default of the port, or \"none\"");
  if (n.control_socket != "none") n.control_socket = c.path(n.control_socket);
  c.string(t, "network.", "control_dir", n.control_dir,
           "the directory record-start writes into, or \"\" for the daemon's working directory");
  n.control_dir = c.path(n.control_dir);
  c.string(t, "network.", "calibration_dir", n.calibration_dir,
           "the directory calibration-load reads from, or \"\" for control_dir");
  n.calibration_dir = c.path(n.calibration_dir);
  if (const toml::node* node = t.get("control_allow")) parse_control_allow(c, *node, n.control_allow);
}

// [record]: the recording path, resolved against the file's directory.
void parse_record(Checker& c, const toml::table& t, RecordConfig& record) {
  c.only(t, "record.", {"path", "append"});
  c.string(t, "record.", "path", record.path, "a .fgr file name, or \"\" for none");
  record.path = c.path(record.path);
  c.boolean(t, "record.", "append", record.append);
}

// [calibration]: the calibration file, resolved against the file's directory and read now.
void parse_calibration(Checker& c, const toml::table& t, CalibrationConfig& calibration) {
  c.only(t, "calibration.", {"file"});
  c.string(t, "calibration.", "file", calibration.file, "a calibration JSON file, or \"\" for none");
  calibration.file = c.path(calibration.file);
  if (!calibration.file.empty()) check_calibration_file(c, *t.get("file"), calibration.file);
}

// [classifier]: the method name (the classify module validates it) and the PSO convention.
void parse_classifier(Checker& c, const toml::table& t, ClassifierConfig& classifier) {
  c.only(t, "classifier.", {"method", "pso", "pursuit_weight"});
  c.string(t, "classifier.", "method", classifier.method,
           "a classifier name or \"source\" (fovea-ctl classify --help describes them)");
  c.string(t, "classifier.", "pso", classifier.pso, "separate, onset, none");
  // Checked here, so --check-config refuses it and the daemon exits 78 (issue 23 item 10: it passed
  // the check, and the daemon then exited 2, which the unit restarts on).
  if (const auto* node = t.get("method"); node != nullptr && node->is_string()) {
    if (const std::string err = check_classifier_method(classifier.method); !err.empty()) {
      c.problem(node->source(), "classifier.method", err);
    }
  }
  if (const auto* node = t.get("pso"); node != nullptr && node->is_string()) {
    if (const std::string err = check_classifier_pso(classifier.method, classifier.pso); !err.empty()) {
      c.problem(node->source(), "classifier.pso", err);
      classifier.pso = "separate";
    }
  }
  c.number(t, "classifier.", "pursuit_weight", classifier.pursuit_weight, 0, 100, false,
           "(0: the model's own; gbt only)");
  if (const auto* node = t.get("pursuit_weight"); node != nullptr && classifier.pursuit_weight != 0) {
    if (const std::string err = check_classifier_pursuit_weight(classifier.method, classifier.pursuit_weight);
        !err.empty()) {
      c.problem(node->source(), "classifier.pursuit_weight", err);
      classifier.pursuit_weight = 0;
    }
  }
}

// [eye]: the eye pipeline (side, LED layout, pupil search) and the synthetic eye's settings.
void parse_eye(Checker& c, const toml::table& t, EyeConfig& eye) {
  c.only(t, "eye.",
         {"side", "leds", "pupil_downscale", "pupil_roi", "synthetic_width", "synthetic_height", "synthetic_hard",
          "synthetic_script", "synthetic_head_offset_mm"});
  c.string(t, "eye.", "side", eye.side, "left, right");
  if (std::find(kEyeSides.begin(), kEyeSides.end(), eye.side) == kEyeSides.end()) {
    c.problem(t.get("side")->source(), "eye.side",
              "\"" + eye.side + "\" is not an eye; allowed: " + join(kEyeSides, ", "));
    eye.side = "right";
  }
  // The layout's syntax is checked by the eye module when the source starts (and --check-config).
  c.string(t, "eye.", "leds", eye.leds,
           "a preset \"0\"..\"5\", \"x,y;x,y;...\" in mm, or \"\" for the source's default");
  c.integer(t, "eye.", "pupil_downscale", eye.pupil_downscale, 1, 4);
  if (eye.pupil_downscale == 3) {
    c.problem(t.get("pupil_downscale")->source(), "eye.pupil_downscale", "3 is not allowed; allowed: 1, 2, 4");
    eye.pupil_downscale = 2;
  }
  c.boolean(t, "eye.", "pupil_roi", eye.pupil_roi);
  c.integer(t, "eye.", "synthetic_width", eye.synthetic_width, 32, 4096);
  c.integer(t, "eye.", "synthetic_height", eye.synthetic_height, 32, 4096);
  c.boolean(t, "eye.", "synthetic_hard", eye.synthetic_hard);
  // Their syntax is checked by the daemon when the source starts (and --check-config).
  c.string(t, "eye.", "synthetic_script", eye.synthetic_script, "\"\" or \"calibration:POINTS[:SEED[:VALIDATION]]\"");
  c.string(t, "eye.", "synthetic_head_offset_mm", eye.synthetic_head_offset_mm, "\"x,y,z\" in mm");
}

// [lsl]: the LSL outlet; asking for it in a build without liblsl is a problem of the file.
void parse_lsl(Checker& c, const toml::table& t, LslConfig& lsl) {
  c.only(t, "lsl.", {"outlet", "name"});
  c.boolean(t, "lsl.", "outlet", lsl.outlet);
  c.string(t, "lsl.", "name", lsl.name, "the streams' name prefix (\"<name> gaze\", \"<name> markers\", \"<name> events\")");
  if (lsl.outlet && !lsl_available()) c.problem(t.get("outlet")->source(), "lsl.outlet", lsl_library_info());
  if (lsl.name.empty() && t.get("name") != nullptr)
    c.problem(t.get("name")->source(), "lsl.name", "empty; allowed: a non-empty name");
}

// [log]: the log level; an unknown one falls back to info after the problem is noted.
void parse_log(Checker& c, const toml::table& t, std::string& log_level) {
  c.only(t, "log.", {"level"});
  c.string(t, "log.", "level", log_level, "trace, debug, info, warn, error");
  if (std::find(kLogLevels.begin(), kLogLevels.end(), log_level) == kLogLevels.end()) {
    c.problem(t.get("level")->source(), "log.level",
              "\"" + log_level + "\" is not a level; allowed: " + join(kLogLevels, ", "));
    log_level = "info";
  }
}

// One [[devices]] entry: vid, pid, kind and name, each required.
DeviceEntry parse_device(Checker& c, const toml::table& t, const std::string& prefix) {
  c.only(t, prefix, {"vid", "pid", "kind", "name"});
  DeviceEntry d;
  usb_id(c, t, prefix, "vid", d.vid);
  usb_id(c, t, prefix, "pid", d.pid);
  c.string(t, prefix, "kind", d.kind, "hid, camera");
  if (!t.contains("kind")) {
    c.problem(t.source(), prefix + "kind", "missing; allowed: " + join(kDeviceKinds, ", "));
  } else if (t.get("kind")->is_string() &&
             std::find(kDeviceKinds.begin(), kDeviceKinds.end(), d.kind) == kDeviceKinds.end()) {
    c.problem(t.get("kind")->source(), prefix + "kind",
              "\"" + d.kind + "\" is not a device kind; allowed: " + join(kDeviceKinds, ", "));
  }
  c.string(t, prefix, "name", d.name);
  return d;
}

// [[devices]]: the known trackers and eye cameras, each vid:pid at most once.
void parse_devices(Checker& c, const toml::node& node, std::vector<DeviceEntry>& devices) {
  if (!node.is_array_of_tables()) {
    c.problem(node.source(), "devices",
              std::string("must be an array of tables ([[devices]] entries), not ") + type_name(node));
  } else {
    std::size_t i = 0;
    for (const toml::node& el : *node.as_array()) {
      const std::string prefix = fmt::format("devices[{}].", i++);
      const toml::table& t = *el.as_table();
      const DeviceEntry d = parse_device(c, t, prefix);
      for (const auto& other : devices) {
        if (other.vid == d.vid && other.pid == d.pid) {
          c.problem(t.source(), prefix + "vid", fmt::format("{:04x}:{:04x} is listed twice", d.vid, d.pid));
        }
      }
      devices.push_back(d);
    }
  }
}

DaemonConfig parse_table(const toml::table& doc, Checker& c) {
  DaemonConfig cfg;
  cfg.origin = c.origin_;
  c.only(doc, "", {"source", "display", "network", "record", "calibration", "classifier", "eye", "lsl", "devices", "log"});
  if (const auto* t = c.table(doc, "source")) parse_source(c, *t, cfg.source);
  if (const auto* t = c.table(doc, "display")) parse_display(c, *t, cfg.display);
  if (const auto* t = c.table(doc, "network")) parse_network(c, *t, cfg.network);
  if (const auto* t = c.table(doc, "record")) parse_record(c, *t, cfg.record);
  if (const auto* t = c.table(doc, "calibration")) parse_calibration(c, *t, cfg.calibration);
  if (const auto* t = c.table(doc, "classifier")) parse_classifier(c, *t, cfg.classifier);
  if (const auto* t = c.table(doc, "eye")) parse_eye(c, *t, cfg.eye);
  if (const auto* t = c.table(doc, "lsl")) parse_lsl(c, *t, cfg.lsl);
  if (const auto* t = c.table(doc, "log")) parse_log(c, *t, cfg.log_level);
  if (const toml::node* node = doc.get("devices")) parse_devices(c, *node, cfg.devices);
  return cfg;
}

// A TOML basic string.
std::string quoted(const std::string& s) {
  std::string out = "\"";
  for (const char ch : s) {
    const auto u = static_cast<unsigned char>(ch);
    if (ch == '"' || ch == '\\') {
      out += '\\';
      out += ch;
    } else if (u < 0x20 || u == 0x7F) {
      out += fmt::format("\\u{:04X}", static_cast<unsigned>(u));
    } else {
      out += ch;
    }
  }
  return out + "\"";
}

}  // namespace

ConfigError::ConfigError(std::vector<std::string> problems)
    : std::runtime_error(join(problems)), problems_(std::move(problems)) {}

DaemonConfig parse_config(const std::string& text, const std::string& origin, const std::string& base_dir) {
  toml::table doc;
  try {
    doc = toml::parse(text, origin);
  } catch (const toml::parse_error& e) {
    throw ConfigError(
        {fmt::format("{}:{}:{}: {}", origin, e.source().begin.line, e.source().begin.column, e.description())});
  }
  Checker c(origin, base_dir);
  DaemonConfig cfg = parse_table(doc, c);
  if (!c.problems().empty()) throw ConfigError(c.problems());
  return cfg;
}

DaemonConfig load_config(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw ConfigError({path + ": cannot read configuration file (" + std::strerror(errno) + ")"});
  std::stringstream ss;
  ss << in.rdbuf();
  const std::filesystem::path dir = std::filesystem::absolute(path).parent_path();
  return parse_config(ss.str(), path, dir.string());
}

void apply_overrides(DaemonConfig& c, const CliOverrides& o) {
  if (o.source) c.source.spec = *o.source;
  if (o.rate_hz) c.source.rate_hz = *o.rate_hz;
  if (o.seed) c.source.seed = *o.seed;
  if (o.speed) c.source.speed = *o.speed;
  if (o.loop) c.source.loop = *o.loop;
  if (o.lsl_outlet) c.lsl.outlet = *o.lsl_outlet;
  if (o.display) c.display = *o.display;
  if (o.listen) c.network.listen = *o.listen;
  if (o.port) c.network.port = *o.port;
  if (o.multicast) c.network.multicast = *o.multicast;
  if (o.multicast_ttl) c.network.multicast_ttl = *o.multicast_ttl;
  if (o.max_subscribers) c.network.max_subscribers = *o.max_subscribers;
  if (o.lease_ms) c.network.lease_ms = *o.lease_ms;
  if (o.control_socket) c.network.control_socket = *o.control_socket;
  if (o.control_dir) c.network.control_dir = *o.control_dir;
  if (o.record_path) c.record.path = *o.record_path;
  if (o.record_append) c.record.append = *o.record_append;
  if (o.classifier_method) c.classifier.method = *o.classifier_method;
  if (o.classifier_pso) c.classifier.pso = *o.classifier_pso;
  if (o.classifier_pursuit_weight) c.classifier.pursuit_weight = *o.classifier_pursuit_weight;
  if (o.calibration_file) c.calibration.file = *o.calibration_file;
  if (o.log_level) c.log_level = *o.log_level;
  if (o.eye_side) c.eye.side = *o.eye_side;
  if (o.eye_leds) c.eye.leds = *o.eye_leds;
  if (o.pupil_downscale) c.eye.pupil_downscale = *o.pupil_downscale;
  if (o.pupil_roi) c.eye.pupil_roi = *o.pupil_roi;
  if (o.synthetic_size) {
    c.eye.synthetic_width = o.synthetic_size->first;
    c.eye.synthetic_height = o.synthetic_size->second;
  }
  if (o.synthetic_hard) c.eye.synthetic_hard = *o.synthetic_hard;
  if (o.synthetic_script) c.eye.synthetic_script = *o.synthetic_script;
  if (o.synthetic_head_offset_mm) c.eye.synthetic_head_offset_mm = *o.synthetic_head_offset_mm;
}

std::string to_toml(const DaemonConfig& c) {
  std::string out = "# effective configuration (" + c.origin + " + command line)\n";
  out += "[source]\n";
  out += "spec = " + quoted(c.source.spec) + "\n";
  if (c.source.rate_hz > 0) {
    out += fmt::format("rate = {}\n", c.source.rate_hz);
  } else {
    out += "# rate: the source's default\n";
  }
  out += fmt::format("seed = {}\nspeed = {}\nloop = {}\n", c.source.seed, c.source.speed, c.source.loop);
  if (c.display) {
    const auto& g = *c.display;
    out += fmt::format("\n[display]\nwidth_px = {}\nheight_px = {}\nwidth_mm = {}\nheight_mm = {}\ndistance_mm = {}\n",
                       g.width_px, g.height_px, g.width_m * 1000, g.height_m * 1000, g.viewing_distance_m * 1000);
  } else {
    out += "\n# [display]: the source's own geometry\n";
  }
  const auto& n = c.network;
  out += "\n[network]\nlisten = " + quoted(n.listen) + fmt::format("\nport = {}\n", n.port);
  out += "multicast = " + quoted(n.multicast) + "\n";
  out += fmt::format("multicast_ttl = {}\nmax_subscribers = {}\nlease_ms = {}\n", n.multicast_ttl, n.max_subscribers,
                     n.lease_ms);
  out += "control_socket = " + quoted(n.control_socket) + "\n";
  out += "control_dir = " + quoted(n.control_dir) + "\n";
  out += "calibration_dir = " + quoted(n.calibration_dir) + "\n";
  if (!n.control_allow.empty()) {
    std::vector<std::string> nets;
    for (const auto& a : n.control_allow) nets.push_back(quoted(a.to_string()));
    out += "# ignored: control commands come only through the control socket\n";
    out += "control_allow = [" + join(nets, ", ") + "]\n";
  }
  out += "\n[record]\npath = " + quoted(c.record.path) + fmt::format("\nappend = {}\n", c.record.append);
  out += "\n[calibration]\nfile = " + quoted(c.calibration.file) + "\n";
  out += "\n[classifier]\nmethod = " + quoted(c.classifier.method) + "\npso = " + quoted(c.classifier.pso) + "\n";
  out += fmt::format("pursuit_weight = {}\n", c.classifier.pursuit_weight);
  out += "\n[eye]\nside = " + quoted(c.eye.side) + "\nleds = " + quoted(c.eye.leds) + "\n";
  out += fmt::format("pupil_downscale = {}\npupil_roi = {}\nsynthetic_width = {}\nsynthetic_height = {}\n"
                     "synthetic_hard = {}\n",
                     c.eye.pupil_downscale, c.eye.pupil_roi, c.eye.synthetic_width, c.eye.synthetic_height,
                     c.eye.synthetic_hard);
  out += "synthetic_script = " + quoted(c.eye.synthetic_script) + "\n";
  out += "synthetic_head_offset_mm = " + quoted(c.eye.synthetic_head_offset_mm) + "\n";
  out += fmt::format("\n[lsl]\noutlet = {}\nname = ", c.lsl.outlet) + quoted(c.lsl.name) + "\n";
  out += "\n[log]\nlevel = " + quoted(c.log_level) + "\n";
  for (const auto& d : c.devices) {
    out += fmt::format("\n[[devices]]\nvid = 0x{:04x}\npid = 0x{:04x}\nkind = {}\nname = {}\n", d.vid, d.pid,
                       quoted(d.kind), quoted(d.name));
  }
  return out;
}

protocol::ServerOptions server_options(const DaemonConfig& c) {
  protocol::ServerOptions so;
  so.listen = protocol::parse_endpoint(c.network.listen, c.network.port);
  so.listen.port = c.network.port;
  if (!c.network.multicast.empty()) {
    so.multicast = protocol::parse_multicast(c.network.multicast);
    so.multicast->ttl = static_cast<std::uint8_t>(c.network.multicast_ttl);
  }
  so.default_lease_ms = c.network.lease_ms;
  so.max_subscribers = c.network.max_subscribers;
  so.control_allow = {};  // UDP control is never executed: the control socket is the way (issue 23)
  return so;
}

ConfigChanges diff(const DaemonConfig& a, const DaemonConfig& b) {
  ConfigChanges ch;
  const auto note = [](std::vector<std::string>& to, const char* key, const auto& x, const auto& y) {
    if (!(x == y)) to.push_back(fmt::format("{} {} -> {}", key, x, y));
  };
  const auto text = [](const std::string& s) { return s.empty() ? std::string("(none)") : s; };
  const auto display = [](const std::optional<protocol::DisplayGeometry>& g) {
    return g ? protocol::to_string(*g) : std::string("(the source's)");
  };
  // Live: the daemon applies these without closing its socket or dropping a session.
  note(ch.live, "display", display(a.display), display(b.display));
  note(ch.live, "network.lease_ms", a.network.lease_ms, b.network.lease_ms);
  note(ch.live, "network.max_subscribers", a.network.max_subscribers, b.network.max_subscribers);
  note(ch.live, "network.control_dir", text(a.network.control_dir), text(b.network.control_dir));
  note(ch.live, "network.calibration_dir", text(a.network.calibration_dir), text(b.network.calibration_dir));
  note(ch.live, "record.path", text(a.record.path), text(b.record.path));
  note(ch.live, "record.append", a.record.append, b.record.append);
  note(ch.live, "calibration.file", text(a.calibration.file), text(b.calibration.file));
  note(ch.live, "classifier.method", text(a.classifier.method), text(b.classifier.method));
  note(ch.live, "classifier.pso", a.classifier.pso, b.classifier.pso);
  note(ch.live, "classifier.pursuit_weight", a.classifier.pursuit_weight, b.classifier.pursuit_weight);
  note(ch.live, "log.level", a.log_level, b.log_level);
  // Restart: the socket, the source and device discovery are set up once.
  note(ch.needs_restart, "source.spec", a.source.spec, b.source.spec);
  const auto socket = [](const std::string& s) { return s.empty() ? std::string("(the default)") : s; };
  note(ch.needs_restart, "network.control_socket", socket(a.network.control_socket), socket(b.network.control_socket));
  const auto rate = [](double r) { return r > 0 ? fmt::format("{}", r) : std::string("(the source's default)"); };
  note(ch.needs_restart, "source.rate", rate(a.source.rate_hz), rate(b.source.rate_hz));
  note(ch.needs_restart, "source.seed", a.source.seed, b.source.seed);
  note(ch.needs_restart, "source.speed", a.source.speed, b.source.speed);
  note(ch.needs_restart, "source.loop", a.source.loop, b.source.loop);
  note(ch.needs_restart, "lsl.outlet", a.lsl.outlet, b.lsl.outlet);
  note(ch.needs_restart, "lsl.name", a.lsl.name, b.lsl.name);
  note(ch.needs_restart, "eye.side", a.eye.side, b.eye.side);
  note(ch.needs_restart, "eye.leds", text(a.eye.leds), text(b.eye.leds));
  note(ch.needs_restart, "eye.pupil_downscale", a.eye.pupil_downscale, b.eye.pupil_downscale);
  note(ch.needs_restart, "eye.pupil_roi", a.eye.pupil_roi, b.eye.pupil_roi);
  note(ch.needs_restart, "eye.synthetic_width", a.eye.synthetic_width, b.eye.synthetic_width);
  note(ch.needs_restart, "eye.synthetic_height", a.eye.synthetic_height, b.eye.synthetic_height);
  note(ch.needs_restart, "eye.synthetic_hard", a.eye.synthetic_hard, b.eye.synthetic_hard);
  note(ch.needs_restart, "eye.synthetic_script", text(a.eye.synthetic_script), text(b.eye.synthetic_script));
  note(ch.needs_restart, "eye.synthetic_head_offset_mm", text(a.eye.synthetic_head_offset_mm),
       text(b.eye.synthetic_head_offset_mm));
  note(ch.needs_restart, "network.listen", a.network.listen, b.network.listen);
  note(ch.needs_restart, "network.port", a.network.port, b.network.port);
  note(ch.needs_restart, "network.multicast", text(a.network.multicast), text(b.network.multicast));
  note(ch.needs_restart, "network.multicast_ttl", a.network.multicast_ttl, b.network.multicast_ttl);
  if (!(a.devices == b.devices)) {
    ch.needs_restart.push_back(fmt::format("devices ({} entries -> {})", a.devices.size(), b.devices.size()));
  }
  return ch;
}

DaemonConfig adopt_live(const DaemonConfig& running, const DaemonConfig& next) {
  DaemonConfig out = next;
  out.source = running.source;
  out.eye = running.eye;  // the source is built once
  out.network.listen = running.network.listen;
  out.network.port = running.network.port;
  out.network.multicast = running.network.multicast;
  out.network.multicast_ttl = running.network.multicast_ttl;
  out.network.control_socket = running.network.control_socket;
  out.devices = running.devices;
  out.lsl = running.lsl;  // the outlets are opened once
  return out;
}

}  // namespace fovea::trackerd::service
