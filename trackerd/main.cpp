// fovea-trackerd: the eye-tracking daemon.
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <atomic>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <stdexcept>
#include <utility>

#include "daemon.h"
#include "service/config.h"
#include "sources/source_table.h"

namespace {
std::atomic<bool> g_stop{false};
std::atomic<bool> g_reload{false};
// Signal handlers only set flags; the publishing loop does the work.
void on_stop(int) { g_stop.store(true); }
void on_hangup(int) { g_reload.store(true); }

// Exit status for an unusable configuration file (sysexits.h EX_CONFIG); the service unit does not
// restart on it (RestartPreventExitStatus=78): a restart would fail the same way.
constexpr int kExitConfig = 78;
}  // namespace

int main(int argc, char** argv) {
  using namespace fovea;
  namespace svc = trackerd::service;
  CLI::App app{
      "fovea-trackerd: reads an eye tracker (or a synthetic or recorded gaze stream) and streams gaze samples and\n"
      "events over UDP to subscribed clients (protocol: protocol/PROTOCOL.md). Settings come from --config FILE\n"
      "(TOML, documented in deploy/trackerd.toml) and the flags below, which override the file.\n"
      "SIGINT/SIGTERM stop it cleanly; SIGHUP reloads the configuration and calibration without dropping subscribers."};
  app.set_version_flag("--version", "fovea-trackerd 0.1.0");

  const svc::DaemonConfig defaults;
  svc::DaemonConfig d = defaults;  // receives the flag values; only flags given on the command line count
  std::string config_path, display, multicast, log_level = defaults.log_level, record_path, calibration, classifier;
  std::vector<std::string> control_allow;
  bool check_config = false, loop = false, append = false;
  trackerd::RunOptions run;

  app.add_option("--config", config_path,
                 std::string("TOML configuration file (the service uses ") + svc::kDefaultConfigPath +
                     "); flags override its values");
  app.add_flag(
      "--check-config", check_config,
      std::string("validate the configuration (--config FILE, default ") + svc::kDefaultConfigPath +
          ") with the flags applied, print the effective configuration and exit 0, or the problems and exit 1");
  auto* o_source =
      app.add_option("--source", d.source.spec, trackerd::source_help())
          ->capture_default_str();
  auto* o_port = app.add_option("--port", d.network.port, "UDP port to serve on")->capture_default_str();
  auto* o_listen =
      app.add_option("--listen", d.network.listen, "local IPv4 address to bind (0.0.0.0 to serve other machines)")
          ->capture_default_str();
  auto* o_multicast = app.add_option("--multicast", multicast,
                                     "also publish samples and events to GROUP:PORT (e.g. 239.255.47.80:47801)");
  auto* o_ttl = app.add_option("--multicast-ttl", d.network.multicast_ttl, "multicast TTL (1: this LAN segment)")
                    ->check(CLI::Range(0, 255))
                    ->capture_default_str();
  auto* o_record =
      app.add_option("--record", record_path, "record everything published to this .fgr file (refuses to overwrite)");
  auto* o_append =
      app.add_flag("--append", append, "with --record: append to an existing recording of the same display");
  auto* o_rate = app.add_option("--rate", d.source.rate_hz,
                                "synthetic sources: sample (frame) rate in Hz; synthetic 1..10000 (default 250), "
                                "synthetic-eye 1..1000 (default 120)")
                     ->check(CLI::Range(1.0, 10000.0));
  auto* o_seed =
      app.add_option("--seed", d.source.seed, "synthetic sources: random seed (same seed, same gaze)")
          ->capture_default_str();
  // The eye pipeline (camera:, video:, synthetic-eye).
  std::string eye_side = defaults.eye.side, leds, eye_size, eye_script, eye_head_offset;
  bool no_pupil_roi = false, eye_hard = false;
  auto* o_eye = app.add_option("--eye", eye_side, "eye pipeline: which eye the camera sees (fills that eye's data)")
                    ->check(CLI::IsMember(svc::kEyeSides))
                    ->capture_default_str();
  auto* o_leds = app.add_option("--leds", leds,
                                "eye pipeline: infrared LED layout around the camera lens, a preset 0..5 or "
                                "\"x,y;x,y;...\" in mm (default: synthetic-eye 2, cameras and videos unknown)");
  auto* o_downscale = app.add_option("--pupil-downscale", d.eye.pupil_downscale,
                                     "eye pipeline: coarse pupil search on an image 1, 2 or 4 times smaller")
                          ->check(CLI::IsMember({1, 2, 4}))
                          ->capture_default_str();
  auto* o_no_roi =
      app.add_flag("--no-pupil-roi", no_pupil_roi, "eye pipeline: search the whole frame every time (no tracking ROI)");
  auto* o_eye_size =
      app.add_option("--eye-size", eye_size, "synthetic-eye: eye camera image size WxH (default 320x240)");
  auto* o_eye_hard = app.add_flag("--eye-hard", eye_hard,
                                  "synthetic-eye: hard imaging conditions (sensor noise 10, 2 px motion blur, upper "
                                  "lid over 30% of the pupil, spectacle reflections, uneven illumination)");
  auto* o_eye_script = app.add_option(
      "--eye-script", eye_script,
      "synthetic-eye: calibration:POINTS[:SEED[:VALIDATION]] makes the viewer follow the targets that "
      "'fovea-calibrate run --points POINTS --seed SEED --validation-points VALIDATION' shows (defaults 1 "
      "and 4), starting with the first frame: a whole calibration without a person");
  auto* o_eye_head_offset = app.add_option(
      "--eye-head-offset", eye_head_offset,
      "synthetic-eye: X,Y,Z mm, the viewer's head moved from where the factory calibration assumes it "
      "(x right, y down, z towards the screen)");
  auto* o_speed = app.add_option("--speed", d.source.speed, "replay source: speed factor (2 = twice as fast)")
                      ->capture_default_str();
  auto* o_loop = app.add_flag("--loop", loop, "replay source: start again at the end");
  auto* o_display = app.add_option(
      "--display", display,
      "display geometry WxH@WMMxHMMmm,DISTmm (default: the recording's, or 1920x1080@531.3x298.9mm,650mm)");
  auto* o_lease =
      app.add_option("--lease-ms", d.network.lease_ms, "lease granted to subscribers that do not ask for one")
          ->check(CLI::Range(200u, 600000u))
          ->capture_default_str();
  auto* o_max = app.add_option("--max-subscribers", d.network.max_subscribers, "refuse subscriptions beyond this many")
                    ->capture_default_str();
  auto* o_allow = app.add_option("--control-allow", control_allow,
                                 "networks allowed to send control commands (reload, record-start/stop), A.B.C.D/N; "
                                 "repeat or separate with commas (default 127.0.0.0/8)")
                      ->delimiter(',');
  auto* o_calibration = app.add_option("--calibration", calibration, "calibration file (JSON)");
  auto* o_classifier = app.add_option("--classifier", classifier,
                                       "online classifier: ivvt (default), ivt, idt, lee2009, or 'source' to pass "
                                       "the source's own labels and events (trackerd/CLASSIFY.md)");
  app.add_option("--duration", run.duration_s, "stop after this many seconds (0: run until signalled)")
      ->capture_default_str();
  app.add_flag("--exit-at-end", run.exit_when_source_ends, "exit when the source ends (default: keep serving status)");
  app.add_option("--wait-subscribers", run.wait_subscribers,
                 "start the source only once this many clients have subscribed (regression tests)");
  auto* o_log = app.add_option("--log-level", log_level, "log verbosity")
                    ->check(CLI::IsMember({"trace", "debug", "info", "warn", "error"}))
                    ->capture_default_str();
  CLI11_PARSE(app, argc, argv);

  auto logger = spdlog::stderr_color_mt("fovea-trackerd");
  // Under systemd the journal stamps every line itself.
  logger->set_pattern(std::getenv("JOURNAL_STREAM") != nullptr ? "%^%-5l%$ %v"
                                                               : "%Y-%m-%dT%H:%M:%S.%e %^%-5l%$ fovea-trackerd: %v");
  spdlog::set_default_logger(logger);
  spdlog::set_level(spdlog::level::from_str(log_level));

  // Flags given on the command line override the file, now and on every reload.
  svc::CliOverrides cli;
  try {
    const auto given = [](const CLI::Option* o) { return o->count() > 0; };
    if (given(o_source)) cli.source = d.source.spec;
    if (given(o_rate)) cli.rate_hz = d.source.rate_hz;
    if (given(o_seed)) cli.seed = d.source.seed;
    if (given(o_speed)) cli.speed = d.source.speed;
    if (given(o_loop)) cli.loop = loop;
    if (given(o_display)) cli.display = protocol::parse_display_geometry(display);
    if (given(o_listen)) cli.listen = d.network.listen;
    if (given(o_port)) cli.port = d.network.port;
    if (given(o_multicast)) {
      if (!multicast.empty()) (void)protocol::parse_multicast(multicast);
      cli.multicast = multicast;
    }
    if (given(o_ttl)) cli.multicast_ttl = d.network.multicast_ttl;
    if (given(o_max)) cli.max_subscribers = d.network.max_subscribers;
    if (given(o_lease)) cli.lease_ms = d.network.lease_ms;
    if (given(o_allow)) {
      std::vector<protocol::Ipv4Cidr> nets;
      for (const auto& text : control_allow) nets.push_back(protocol::parse_cidr(text));
      cli.control_allow = nets;
    }
    if (given(o_record)) cli.record_path = record_path;
    if (given(o_append)) cli.record_append = append;
    if (given(o_calibration)) cli.calibration_file = calibration;
    if (given(o_classifier)) cli.classifier_method = classifier;
    if (given(o_log)) cli.log_level = log_level;
    if (given(o_eye)) cli.eye_side = eye_side;
    if (given(o_leds)) cli.eye_leds = leds;
    if (given(o_downscale)) cli.pupil_downscale = d.eye.pupil_downscale;
    if (given(o_no_roi)) cli.pupil_roi = !no_pupil_roi;
    if (given(o_eye_hard)) cli.synthetic_hard = eye_hard;
    if (given(o_eye_script)) cli.synthetic_script = eye_script;
    if (given(o_eye_head_offset)) cli.synthetic_head_offset_mm = eye_head_offset;
    if (given(o_eye_size)) {
      unsigned w = 0, h = 0;
      char tail = 0;
      if (std::sscanf(eye_size.c_str(), "%ux%u%c", &w, &h, &tail) != 2 || w < 32 || h < 32 || w > 4096 || h > 4096) {
        throw std::invalid_argument("--eye-size \"" + eye_size + "\": expected WxH, each 32..4096 (e.g. 320x240)");
      }
      cli.synthetic_size = std::pair{std::uint32_t{w}, std::uint32_t{h}};
    }
    if (given(o_listen)) (void)protocol::parse_endpoint(d.network.listen, d.network.port);
  } catch (const std::exception& e) {
    spdlog::error("{}", e.what());
    return 2;
  }

  if (check_config && config_path.empty()) config_path = svc::kDefaultConfigPath;
  const trackerd::ConfigLoader load = [config_path, cli] {
    svc::DaemonConfig c = config_path.empty() ? svc::DaemonConfig{} : svc::load_config(config_path);
    svc::apply_overrides(c, cli);
    return c;
  };

  if (check_config) {
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

  svc::DaemonConfig config;
  try {
    config = load();
  } catch (const svc::ConfigError& e) {
    spdlog::error("configuration {} is invalid:\n{}", config_path, e.what());
    return kExitConfig;
  }
  spdlog::set_level(spdlog::level::from_str(config.log_level));  // the file's, unless --log-level
  if (!config_path.empty()) spdlog::info("configuration {}", config_path);

  // A scripted synthetic viewer follows the calibration from its first frame: hold the source until
  // the calibration tool has subscribed, so that the script and the targets start together.
  if (config.source.spec == "synthetic-eye" && !config.eye.synthetic_script.empty() && run.wait_subscribers == 0) {
    run.wait_subscribers = 1;
    spdlog::info("--eye-script: the source starts when the first client subscribes");
  }

  struct sigaction sa {};
  sigemptyset(&sa.sa_mask);
  sa.sa_handler = on_stop;
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);
  sa.sa_handler = on_hangup;
  sigaction(SIGHUP, &sa, nullptr);
  std::signal(SIGPIPE, SIG_IGN);

  const int status = trackerd::run_daemon(config, run, trackerd::DaemonSignals{&g_stop, &g_reload}, load);
  if (g_stop.load()) spdlog::info("signal received, shut down cleanly");
  return status;
}
