// SPDX-License-Identifier: Apache-2.0
// fovea-trackerd: the eye-tracking daemon.
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <atomic>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <cstdlib>
#include <optional>
#include <stdexcept>
#include <utility>

#include "daemon.h"
#include "lsl/lsl_outlet.h"
#include "service/config.h"
#include "sources/source_table.h"

namespace {
namespace protocol = fovea::protocol;
namespace trackerd = fovea::trackerd;
namespace svc = fovea::trackerd::service;

std::atomic<bool> g_stop{false};
std::atomic<bool> g_reload{false};
// Signal handlers only set flags; the publishing loop does the work.
void on_stop(int) { g_stop.store(true); }
void on_hangup(int) { g_reload.store(true); }

// Exit status for an unusable configuration file (sysexits.h EX_CONFIG); the service unit does not
// restart on it (RestartPreventExitStatus=78): a restart would fail the same way.
constexpr int kExitConfig = 78;

// Where CLI11 writes the flag values (it holds references: this must not move once options are added),
// and the options whose count() says whether a flag was given.
struct Flags {
  const svc::DaemonConfig defaults;
  svc::DaemonConfig d = defaults;  // receives the flag values; only flags given on the command line count
  std::string config_path, display, multicast, log_level = defaults.log_level, record_path, calibration, classifier,
      classifier_pso;
  std::string control_socket, control_dir;
  bool check_config = false, loop = false, append = false, lsl = false;
  trackerd::RunOptions run;
  double classifier_pursuit_weight = 0;
  // The eye pipeline (camera:, video:, synthetic-eye).
  std::string eye_side = defaults.eye.side, leds, eye_size, eye_script, eye_head_offset;
  bool no_pupil_roi = false, eye_hard = false;

  CLI::Option *o_source = nullptr, *o_port = nullptr, *o_listen = nullptr, *o_multicast = nullptr, *o_ttl = nullptr,
              *o_record = nullptr, *o_append = nullptr, *o_rate = nullptr, *o_seed = nullptr, *o_lsl = nullptr;
  CLI::Option *o_eye = nullptr, *o_leds = nullptr, *o_downscale = nullptr, *o_no_roi = nullptr, *o_eye_size = nullptr,
              *o_eye_hard = nullptr, *o_eye_script = nullptr, *o_eye_head_offset = nullptr;
  CLI::Option *o_speed = nullptr, *o_loop = nullptr, *o_display = nullptr, *o_lease = nullptr, *o_max = nullptr,
              *o_control_socket = nullptr, *o_control_dir = nullptr, *o_calibration = nullptr, *o_classifier = nullptr,
              *o_classifier_pso = nullptr, *o_classifier_pursuit_weight = nullptr, *o_log = nullptr;
};

// The option groups below are added in --help order; keep it when moving an option.

// --config and --check-config.
void add_config_options(CLI::App& app, Flags& f) {
  app.add_option("--config", f.config_path,
                 std::string("TOML configuration file (the service uses ") + svc::kDefaultConfigPath +
                     "); flags override its values");
  app.add_flag(
      "--check-config", f.check_config,
      std::string("validate the configuration (--config FILE, default ") + svc::kDefaultConfigPath +
          ") with the flags applied, print the effective configuration and exit 0, or the problems and exit 1");
}

// The source, where to serve and record, and the synthetic sources' rate and seed.
void add_source_network_and_record_options(CLI::App& app, Flags& f) {
  svc::DaemonConfig& d = f.d;
  f.o_source =
      app.add_option("--source", d.source.spec, trackerd::source_help())
          ->capture_default_str();
  f.o_port = app.add_option("--port", d.network.port, "UDP port to serve on")->capture_default_str();
  f.o_listen =
      app.add_option("--listen", d.network.listen, "local IPv4 address to bind (0.0.0.0 to serve other machines)")
          ->capture_default_str();
  f.o_multicast = app.add_option("--multicast", f.multicast,
                                 "also publish samples and events to GROUP:PORT (e.g. 239.255.47.80:47801)");
  f.o_ttl = app.add_option("--multicast-ttl", d.network.multicast_ttl, "multicast TTL (1: this LAN segment)")
                ->check(CLI::Range(0, 255))
                ->capture_default_str();
  f.o_record =
      app.add_option("--record", f.record_path, "record everything published to this .fgr file (refuses to overwrite)");
  f.o_append =
      app.add_flag("--append", f.append, "with --record: append to an existing recording of the same display");
  f.o_lsl = app.add_flag("--lsl", f.lsl,
                         "also publish gaze, markers (verbatim) and eye-movement events as Lab Streaming Layer streams "
                         "(types Gaze, Markers and GazeEvents; [lsl] in the configuration; needs a build with liblsl)");
  f.o_rate = app.add_option("--rate", d.source.rate_hz,
                            "synthetic sources: sample (frame) rate in Hz; synthetic 1..10000 (default 250), "
                            "synthetic-eye 1..1000 (default 120)")
                 ->check(CLI::Range(1.0, 10000.0));
  f.o_seed =
      app.add_option("--seed", d.source.seed, "synthetic sources: random seed (same seed, same gaze)")
          ->capture_default_str();
}

// The eye pipeline (camera:, video:, synthetic-eye).
void add_eye_options(CLI::App& app, Flags& f) {
  f.o_eye = app.add_option("--eye", f.eye_side, "eye pipeline: which eye the camera sees (fills that eye's data)")
                ->check(CLI::IsMember(svc::kEyeSides))
                ->capture_default_str();
  f.o_leds = app.add_option("--leds", f.leds,
                            "eye pipeline: infrared LED layout around the camera lens, a preset 0..5 or "
                            "\"x,y;x,y;...\" in mm (default: synthetic-eye 2, cameras and videos unknown)");
  f.o_downscale = app.add_option("--pupil-downscale", f.d.eye.pupil_downscale,
                                 "eye pipeline: coarse pupil search on an image 1, 2 or 4 times smaller")
                      ->check(CLI::IsMember({1, 2, 4}))
                      ->capture_default_str();
  f.o_no_roi = app.add_flag("--no-pupil-roi", f.no_pupil_roi,
                            "eye pipeline: search the whole frame every time (no tracking ROI)");
  f.o_eye_size =
      app.add_option("--eye-size", f.eye_size, "synthetic-eye: eye camera image size WxH (default 320x240)");
  f.o_eye_hard = app.add_flag("--eye-hard", f.eye_hard,
                              "synthetic-eye: hard imaging conditions (sensor noise 10, 2 px motion blur, upper "
                              "lid over 30% of the pupil, spectacle reflections, uneven illumination)");
  f.o_eye_script = app.add_option(
      "--eye-script", f.eye_script,
      "synthetic-eye: calibration:POINTS[:SEED[:VALIDATION]] makes the viewer follow the targets that "
      "'fovea-calibrate run --points POINTS --seed SEED --validation-points VALIDATION' shows (defaults 1 "
      "and 4), starting with the first frame: a whole calibration without a person");
  f.o_eye_head_offset = app.add_option(
      "--eye-head-offset", f.eye_head_offset,
      "synthetic-eye: X,Y,Z mm, the viewer's head moved from where the factory calibration assumes it "
      "(x right, y down, z towards the screen)");
}

// The replay source, the display geometry and what subscribers may do.
void add_replay_display_and_subscriber_options(CLI::App& app, Flags& f) {
  svc::DaemonConfig& d = f.d;
  f.o_speed = app.add_option("--speed", d.source.speed, "replay source: speed factor (2 = twice as fast)")
                  ->capture_default_str();
  f.o_loop = app.add_flag("--loop", f.loop, "replay source: start again at the end");
  f.o_display = app.add_option(
      "--display", f.display,
      "display geometry WxH@WMMxHMMmm,DISTmm (default: the recording's, or 1920x1080@531.3x298.9mm,650mm)");
  f.o_lease =
      app.add_option("--lease-ms", d.network.lease_ms, "lease granted to subscribers that do not ask for one")
          ->check(CLI::Range(200u, 60000u))
          ->capture_default_str();
  f.o_max = app.add_option("--max-subscribers", d.network.max_subscribers, "refuse subscriptions beyond this many")
                ->capture_default_str();
  f.o_control_socket = app.add_option("--control-socket", f.control_socket,
                                      "where control commands (reload, record-start/stop, calibration-load) come "
                                      "from: a Unix socket, mode 0660 (the daemon's user and group); default "
                                      "/run/fovea/control-PORT.sock, else $XDG_RUNTIME_DIR/fovea/ or /tmp/fovea-UID/; "
                                      "none: no control");
  f.o_control_dir = app.add_option("--control-dir", f.control_dir,
                                   "the directory record-start may create recordings in (relative names are "
                                   "relative to it; nothing outside it is written), and calibration-load read "
                                   "calibrations from unless [network] calibration_dir says otherwise; default: the "
                                   "working directory");
}

// Calibration, classifier, how long to run, and the log level.
void add_processing_and_run_options(CLI::App& app, Flags& f) {
  f.o_calibration = app.add_option("--calibration", f.calibration, "calibration file (JSON)");
  f.o_classifier = app.add_option("--classifier", f.classifier,
                                  "online classifier: gbt (default), ivvt, ivt, idt, lee2009, or 'source' to pass "
                                  "the source's own labels and events (trackerd/CLASSIFY.md)");
  f.o_classifier_pso = app.add_option("--classifier-pso", f.classifier_pso,
                                      "gbt: separate (default): the saccade ends as the trees end it (GazeCom's "
                                      "coders), the post-saccadic oscillation after it labelled pso and the small "
                                      "saccades the trees leave in fixations labelled saccade, by ivvt's rule beside "
                                      "the trees; onset: the pso from the oscillation's onset, cutting the saccade "
                                      "there (the EyeLink and Lund coders); none: the trees alone, no PSO class, as "
                                      "GazeCom's coders label, cheaper")
                           ->check(CLI::IsMember({"separate", "onset", "none"}));
  f.o_classifier_pursuit_weight =
      app.add_option("--classifier-pursuit-weight", f.classifier_pursuit_weight,
                     "gbt: the weight of pursuit in the smoothing's choice, 0.01 to 100 (above 1 pursuit sooner "
                     "and more often, below less); 0 (default): the model's own (trackerd/CLASSIFY.md, \"Pursuit "
                     "weight\")");
  app.add_option("--duration", f.run.duration_s, "stop after this many seconds (0: run until signalled)")
      ->capture_default_str();
  app.add_flag("--exit-at-end", f.run.exit_when_source_ends,
               "exit when the source ends (default: keep serving status)");
  app.add_option("--wait-subscribers", f.run.wait_subscribers,
                 "start the source only once this many clients have subscribed (regression tests)");
  f.o_log = app.add_option("--log-level", f.log_level, "log verbosity")
                ->check(CLI::IsMember({"trace", "debug", "info", "warn", "error"}))
                ->capture_default_str();
}

void set_up_logging(const std::string& log_level) {
  auto logger = spdlog::stderr_color_mt("fovea-trackerd");
  // Under systemd the journal stamps every line itself.
  logger->set_pattern(std::getenv("JOURNAL_STREAM") != nullptr ? "%^%-5l%$ %v"
                                                               : "%Y-%m-%dT%H:%M:%S.%e %^%-5l%$ fovea-trackerd: %v");
  spdlog::set_default_logger(logger);
  spdlog::set_level(spdlog::level::from_str(log_level));
}

// --eye-size WxH; throws std::invalid_argument.
std::pair<std::uint32_t, std::uint32_t> parse_eye_size(const std::string& eye_size) {
  unsigned w = 0, h = 0;
  char tail = 0;
  if (std::sscanf(eye_size.c_str(), "%ux%u%c", &w, &h, &tail) != 2 || w < 32 || h < 32 || w > 4096 || h > 4096) {
    throw std::invalid_argument("--eye-size \"" + eye_size + "\": expected WxH, each 32..4096 (e.g. 320x240)");
  }
  return std::pair{std::uint32_t{w}, std::uint32_t{h}};
}

// The flags given on the command line, parsed and checked; throws on the first unusable value (checked in
// this order, so the same flag is reported when several are wrong).
svc::CliOverrides cli_overrides(const Flags& f) {
  const svc::DaemonConfig& d = f.d;
  svc::CliOverrides cli;
  const auto given = [](const CLI::Option* o) { return o->count() > 0; };
  if (given(f.o_source)) cli.source = d.source.spec;
  if (given(f.o_rate)) cli.rate_hz = d.source.rate_hz;
  if (given(f.o_seed)) cli.seed = d.source.seed;
  if (given(f.o_speed)) cli.speed = d.source.speed;
  if (given(f.o_loop)) cli.loop = f.loop;
  if (given(f.o_display)) cli.display = protocol::parse_display_geometry(f.display);
  if (given(f.o_listen)) cli.listen = d.network.listen;
  if (given(f.o_port)) cli.port = d.network.port;
  if (given(f.o_multicast)) {
    if (!f.multicast.empty()) (void)protocol::parse_multicast(f.multicast);
    cli.multicast = f.multicast;
  }
  if (given(f.o_ttl)) cli.multicast_ttl = d.network.multicast_ttl;
  if (given(f.o_max)) cli.max_subscribers = d.network.max_subscribers;
  if (given(f.o_lease)) cli.lease_ms = d.network.lease_ms;
  if (given(f.o_control_socket)) cli.control_socket = f.control_socket;
  if (given(f.o_control_dir)) cli.control_dir = std::filesystem::absolute(f.control_dir).lexically_normal().string();
  if (given(f.o_record)) cli.record_path = f.record_path;
  if (given(f.o_append)) cli.record_append = f.append;
  if (given(f.o_lsl)) {
    if (f.lsl && !trackerd::lsl_available()) throw std::invalid_argument("--lsl: " + trackerd::lsl_library_info());
    cli.lsl_outlet = f.lsl;
  }
  if (given(f.o_calibration)) cli.calibration_file = f.calibration;
  if (given(f.o_classifier)) {
    if (const std::string err = svc::check_classifier_method(f.classifier); !err.empty()) {
      throw std::invalid_argument("--classifier: " + err);
    }
    cli.classifier_method = f.classifier;
  }
  if (given(f.o_classifier_pso)) cli.classifier_pso = f.classifier_pso;
  if (given(f.o_classifier_pursuit_weight)) cli.classifier_pursuit_weight = f.classifier_pursuit_weight;
  if (given(f.o_log)) cli.log_level = f.log_level;
  if (given(f.o_eye)) cli.eye_side = f.eye_side;
  if (given(f.o_leds)) cli.eye_leds = f.leds;
  if (given(f.o_downscale)) cli.pupil_downscale = d.eye.pupil_downscale;
  if (given(f.o_no_roi)) cli.pupil_roi = !f.no_pupil_roi;
  if (given(f.o_eye_hard)) cli.synthetic_hard = f.eye_hard;
  if (given(f.o_eye_script)) cli.synthetic_script = f.eye_script;
  if (given(f.o_eye_head_offset)) cli.synthetic_head_offset_mm = f.eye_head_offset;
  if (given(f.o_eye_size)) cli.synthetic_size = parse_eye_size(f.eye_size);
  if (given(f.o_listen)) (void)protocol::parse_endpoint(d.network.listen, d.network.port);
  return cli;
}

// The file (if any) with the command-line flags applied: at start and on every reload.
trackerd::ConfigLoader config_loader(const std::string& config_path, const svc::CliOverrides& cli) {
  return [config_path, cli] {
    svc::DaemonConfig c = config_path.empty() ? svc::DaemonConfig{} : svc::load_config(config_path);
    svc::apply_overrides(c, cli);
    // The file's own pair was checked as it was read; a flag may pair a method with another's pso.
    if (const std::string err = svc::check_classifier_pso(c.classifier.method, c.classifier.pso); !err.empty()) {
      throw svc::ConfigError({"classifier.pso (--classifier-pso): " + err});
    }
    if (const std::string err = svc::check_classifier_pursuit_weight(c.classifier.method, c.classifier.pursuit_weight);
        !err.empty()) {
      throw svc::ConfigError({"classifier.pursuit_weight (--classifier-pursuit-weight): " + err});
    }
    return c;
  };
}

// --check-config: everything the daemon would refuse at start, reported at once; the exit status.
int check_configuration(const trackerd::ConfigLoader& load, const std::string& config_path) {
  try {
    const svc::DaemonConfig c = load();
    std::vector<std::string> problems;
    if (const std::string p = trackerd::check_source_spec(c.source.spec); !p.empty())
      problems.push_back("source.spec: " + p);
    for (const std::string& p : trackerd::check_eye_config(c.eye)) problems.push_back(p);
    try {
      (void)svc::server_options(c);
    } catch (const std::exception& e) {
      problems.push_back(std::string("network: ") + e.what());
    }
    if (!problems.empty()) throw svc::ConfigError(problems);
    std::fputs(svc::to_toml(c).c_str(), stdout);
    std::fprintf(stderr, "fovea-trackerd: configuration %s is valid\n", c.origin.c_str());
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "fovea-trackerd: configuration %s is invalid:\n%s\n", config_path.c_str(), e.what());
    return 1;
  }
}

// The configuration to start with, or nothing (logged) when the file is invalid; other errors propagate.
std::optional<svc::DaemonConfig> load_startup_config(const trackerd::ConfigLoader& load,
                                                     const std::string& config_path) {
  svc::DaemonConfig config;
  try {
    config = load();
  } catch (const svc::ConfigError& e) {
    spdlog::error("configuration {} is invalid:\n{}", config_path.empty() ? "(the flags alone)" : config_path, e.what());
    return std::nullopt;
  }
  spdlog::set_level(spdlog::level::from_str(config.log_level));  // the file's, unless --log-level
  if (!config_path.empty()) spdlog::info("configuration {}", config_path);
  return config;
}

// A scripted synthetic viewer follows the calibration from its first frame: hold the source until
// the calibration tool has subscribed, so that the script and the targets start together.
void hold_source_for_scripted_viewer(const svc::DaemonConfig& config, trackerd::RunOptions& run) {
  if (config.source.spec == "synthetic-eye" && !config.eye.synthetic_script.empty() && run.wait_subscribers == 0) {
    run.wait_subscribers = 1;
    spdlog::info("--eye-script: the source starts when the first client subscribes");
  }
}

void install_signal_handlers() {
  struct sigaction sa {};
  sigemptyset(&sa.sa_mask);
  sa.sa_handler = on_stop;
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);
  sa.sa_handler = on_hangup;
  sigaction(SIGHUP, &sa, nullptr);
  std::signal(SIGPIPE, SIG_IGN);
}
}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "fovea-trackerd: reads an eye tracker (or a synthetic or recorded gaze stream) and streams gaze samples and\n"
      "events over UDP to subscribed clients (protocol: protocol/PROTOCOL.md). Settings come from --config FILE\n"
      "(TOML, documented in deploy/trackerd.toml) and the flags below, which override the file.\n"
      "SIGINT/SIGTERM stop it cleanly; SIGHUP reloads the configuration and calibration without dropping subscribers."};
  app.set_version_flag("--version", "fovea-trackerd " FOVEA_VERSION);

  Flags f;
  add_config_options(app, f);
  add_source_network_and_record_options(app, f);
  add_eye_options(app, f);
  add_replay_display_and_subscriber_options(app, f);
  add_processing_and_run_options(app, f);
  CLI11_PARSE(app, argc, argv);

  set_up_logging(f.log_level);

  // Flags given on the command line override the file, now and on every reload.
  svc::CliOverrides cli;
  try {
    cli = cli_overrides(f);
  } catch (const std::exception& e) {
    spdlog::error("{}", e.what());
    return 2;
  }

  if (f.check_config && f.config_path.empty()) f.config_path = svc::kDefaultConfigPath;
  const trackerd::ConfigLoader load = config_loader(f.config_path, cli);
  if (f.check_config) return check_configuration(load, f.config_path);

  std::optional<svc::DaemonConfig> config = load_startup_config(load, f.config_path);
  if (!config) return kExitConfig;
  hold_source_for_scripted_viewer(*config, f.run);

  install_signal_handlers();
  const int status = trackerd::run_daemon(*config, f.run, trackerd::DaemonSignals{&g_stop, &g_reload}, load);
  if (g_stop.load()) spdlog::info("signal received, shut down cleanly");
  return status;
}
