// SPDX-License-Identifier: Apache-2.0
// fovea-trackerd configuration: the documented example, strict errors that name file:line and
// key, command-line precedence, reload classification, and IPv4 CIDR allow-lists.
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>

#include "lsl/lsl_outlet.h"
#include "service/config.h"

using namespace fovea;
using namespace fovea::trackerd::service;

namespace {

// Expects parse_config(text) to fail with a problem that contains every one of `needles`.
void expect_problem(const std::string& text, std::initializer_list<std::string> needles) {
  try {
    (void)parse_config(text, "test.toml");
    ADD_FAILURE() << "accepted:\n" << text;
  } catch (const ConfigError& e) {
    bool found = false;
    for (const auto& p : e.problems()) {
      bool all = true;
      for (const auto& n : needles) all = all && p.find(n) != std::string::npos;
      found = found || all;
    }
    std::string want;
    for (const auto& n : needles) want += "[" + n + "] ";
    EXPECT_TRUE(found) << "no problem mentions " << want << "in:\n" << e.what();
  }
}

struct TempDir {
  std::filesystem::path path;
  TempDir() {
    char tmpl[] = "/tmp/fovea-config-XXXXXX";
    path = mkdtemp(tmpl);
  }
  ~TempDir() { std::filesystem::remove_all(path); }
  std::string write(const std::string& name, const std::string& text) const {
    std::ofstream(path / name) << text;
    return (path / name).string();
  }
};

}  // namespace

TEST(Config, DocumentedExampleParses) {
  const std::string example = std::string(FOVEA_SOURCE_DIR) + "/deploy/trackerd.toml";
  DaemonConfig c;
  ASSERT_NO_THROW(c = load_config(example)) << example;
  EXPECT_EQ(c.origin, example);
  EXPECT_EQ(c.source.spec, "synthetic");
  EXPECT_EQ(c.network.port, 47800);
  EXPECT_EQ(c.network.listen, "127.0.0.1");
  EXPECT_TRUE(c.network.control_allow.empty()) << "UDP control is off in the example (issue 23)";
  EXPECT_EQ(c.network.control_socket, "") << "the control socket's default path";
  EXPECT_FALSE(c.devices.empty()) << "the example documents [[devices]]";
  EXPECT_EQ(c.eye, EyeConfig{}) << "the example documents [eye] with its defaults";
  EXPECT_EQ(c.source.rate_hz, 0) << "rate is left out: each synthetic source's own default";
  for (const auto& d : c.devices) EXPECT_FALSE(d.name.empty());
}

TEST(Config, EmptyFileIsTheDefaults) {
  const DaemonConfig c = parse_config("", "empty.toml");
  const DaemonConfig d;
  EXPECT_EQ(c.source, d.source);
  EXPECT_EQ(c.network, d.network);
  EXPECT_FALSE(c.display.has_value());
  EXPECT_TRUE(c.devices.empty());
}

TEST(Config, EffectiveConfigurationReadsBack) {
  DaemonConfig c = parse_config(R"(
[source]
spec = "replay:/data/a.fgr"
speed = 2.5
loop = true
[display]
width_px = 2560
height_px = 1440
width_mm = 597
height_mm = 336
distance_mm = 700
[network]
listen = "0.0.0.0"
port = 47900
multicast = "239.255.47.80:47801"
multicast_ttl = 2
max_subscribers = 8
lease_ms = 2000
control_allow = ["127.0.0.0/8", "192.168.1.0/24"]
[record]
path = "/var/lib/fovea/x.fgr"
append = true
[classifier]
method = "gbt"
pso = "none"
pursuit_weight = 1.75
[log]
level = "debug"
[[devices]]
vid = 0x2104
pid = "0127"
kind = "hid"
name = "Tobii \"Pro\" Nano"
)",
                                "full.toml", "/etc/fovea");
  const DaemonConfig back = parse_config(to_toml(c), "printed.toml");
  EXPECT_EQ(back.source, c.source);
  EXPECT_EQ(back.network, c.network);
  EXPECT_TRUE(server_options(c).control_allow.empty()) << "control_allow is parsed but never given to the server";
  EXPECT_EQ(back.record, c.record);
  EXPECT_EQ(back.classifier, c.classifier);
  EXPECT_EQ(c.classifier.pursuit_weight, 1.75);
  EXPECT_EQ(back.devices, c.devices);
  EXPECT_EQ(back.log_level, "debug");
  ASSERT_TRUE(back.display.has_value());
  EXPECT_EQ(back.display->width_px, 2560u);
  EXPECT_NEAR(back.display->viewing_distance_m, 0.7, 1e-12);
  EXPECT_EQ(c.devices[0].vid, 0x2104);
  EXPECT_EQ(c.devices[0].pid, 0x0127);
}

TEST(Config, RelativePathsResolveAgainstTheFilesDirectory) {
  TempDir dir;
  dir.write("cal.json", R"({"model": "identity"})");
  const std::string path = dir.write("t.toml",
                                     "[record]\npath = \"rec/out.fgr\"\n[calibration]\nfile = \"cal.json\"\n"
                                     "[source]\nspec = \"replay:data/x.fgr\"\n");
  const DaemonConfig c = load_config(path);
  EXPECT_EQ(c.record.path, (dir.path / "rec/out.fgr").string());
  EXPECT_EQ(c.calibration.file, (dir.path / "cal.json").string());
  EXPECT_EQ(c.source.spec, "replay:" + (dir.path / "data/x.fgr").string());
}

TEST(Config, ErrorsNameFileLineKeyAndAllowedValues) {
  // line numbers: the key's line in the text (1-based; the raw strings start with a newline).
  expect_problem("\n[network]\nprot = 47800\n", {"test.toml:3:", "network.prot", "unknown key", "port"});
  expect_problem("\n[netwrok]\n", {"test.toml:2:", "netwrok", "unknown key", "network"});
  expect_problem("\n[network]\nport = 70000\n", {"test.toml:3:", "network.port", "70000", "1..65535"});
  expect_problem("\n[network]\nport = \"47800\"\n", {"test.toml:3:", "network.port", "must be an integer"});
  expect_problem("\n\n[network]\nlease_ms = 10\n", {"test.toml:4:", "network.lease_ms", "200..60000"});
  expect_problem("[network]\nmulticast = \"10.0.0.1:5000\"\n",
                 {"test.toml:2:", "network.multicast", "not a multicast group"});
  expect_problem("[network]\ncontrol_allow = [\"127.0.0.1/33\"]\n",
                 {"test.toml:2:", "network.control_allow[0]", "0..32"});
  expect_problem("[network]\ncontrol_allow = \"127.0.0.0/8\"\n",
                 {"test.toml:2:", "network.control_allow", "must be an array"});
  expect_problem("[network]\ncontrol_allow = [\"10.1.2.3/8\"]\n",
                 {"network.control_allow[0]", "did you mean 10.0.0.0/8"});
  expect_problem("[source]\nrate = 0\n", {"test.toml:2:", "source.rate", "[1, 10000] Hz"});
  // Issue 23 item 10: an unknown classifier passed --check-config, then the daemon exited 2.
  expect_problem("[classifier]\nmethod = \"magic\"\n",
                 {"test.toml:2:", "classifier.method", "unknown method \"magic\"", "allowed: gbt", "source"});
  // "source" (the source's own labels and events) is a method the daemon knows, as --help says.
  EXPECT_TRUE(check_classifier_method("source").empty());
  expect_problem("[classifier]\nmethod = \"a\\u001b[2J\"\n", {"unknown method \"a\\x1b[2J\""});
  // Without a PSO class only gbt can label (ivvt finds its PSO by its rule); gbt is the default.
  expect_problem("[classifier]\nmethod = \"ivvt\"\npso = \"none\"\n",
                 {"test.toml:3:", "classifier.pso", "for method gbt only (ivvt"});
  EXPECT_EQ(parse_config("[classifier]\npso = \"none\"\n", "t.toml").classifier.pso, "none");
  expect_problem("[classifier]\nmethod = \"source\"\npso = \"none\"\n", {"test.toml:3:", "classifier.pso", "(source"});
  expect_problem("[classifier]\nmethod = \"gbt\"\npso = \"saccade\"\n",
                 {"test.toml:3:", "classifier.pso", "\"saccade\" is no PSO convention; allowed: separate, onset, none"});
  expect_problem("[classifier]\nmethod = \"ivvt\"\npso = \"onset\"\n",
                 {"test.toml:3:", "classifier.pso", "pso = \"onset\" is for method gbt only (ivvt"});
  EXPECT_EQ(parse_config("[classifier]\npso = \"onset\"\n", "t.toml").classifier.pso, "onset");
  EXPECT_EQ(parse_config("[classifier]\nmethod = \"gbt\"\n", "t.toml").classifier.pso, "separate");
  // Only gbt weighs its classes; 0 is the model's own weight, else 0.01..100 (as fovea-ctl classify).
  expect_problem("[classifier]\nmethod = \"ivvt\"\npursuit_weight = 2\n",
                 {"test.toml:3:", "classifier.pursuit_weight", "for method gbt only (ivvt's pursuit is a rule's"});
  EXPECT_EQ(parse_config("[classifier]\npursuit_weight = 2\n", "t.toml").classifier.pursuit_weight, 2);
  expect_problem("[classifier]\nmethod = \"source\"\npursuit_weight = 2\n",
                 {"test.toml:3:", "classifier.pursuit_weight", "(source passes"});
  expect_problem("[classifier]\nmethod = \"gbt\"\npursuit_weight = -1\n",
                 {"test.toml:3:", "classifier.pursuit_weight", "[0, 100]"});
  expect_problem("[classifier]\nmethod = \"gbt\"\npursuit_weight = 0.001\n",
                 {"test.toml:3:", "classifier.pursuit_weight", "0.001 is out of range", "[0.01, 100]"});
  expect_problem("[classifier]\nmethod = \"gbt\"\npursuit_weight = \"more\"\n",
                 {"test.toml:3:", "classifier.pursuit_weight", "must be a number"});
  EXPECT_EQ(parse_config("[classifier]\nmethod = \"gbt\"\npursuit_weight = 0\n", "t.toml").classifier.pursuit_weight, 0);
  EXPECT_TRUE(check_classifier_pursuit_weight("ivvt", 0).empty());
  expect_problem("[source]\nspeed = -1.5\n", {"test.toml:2:", "source.speed", "(0, 1000]"});
  expect_problem("[source]\nloop = \"yes\"\n", {"test.toml:2:", "source.loop", "true or false"});
  expect_problem("[source]\nspec = \"\"\n", {"test.toml:2:", "source.spec", "synthetic[:binocular], synthetic-eye, replay:FILE"});
  expect_problem("[display]\nwidth_px = 1920\n", {"test.toml:1:", "display.height_px", "missing"});
  expect_problem("[display]\nwidth_px = 0\nheight_px = 1080\nwidth_mm = 531\nheight_mm = 299\ndistance_mm = 650\n",
                 {"test.toml:2:", "display.width_px", "1..65536"});
  expect_problem("[log]\nlevel = \"loud\"\n", {"test.toml:2:", "log.level", "trace, debug, info, warn, error"});
  expect_problem("[[devices]]\nvid = 0x12345\npid = 1\nkind = \"hid\"\nname = \"x\"\n",
                 {"test.toml:2:", "devices[0].vid", "0..0xffff"});
  expect_problem("[[devices]]\nvid = 1\npid = 1\nkind = \"usb\"\nname = \"x\"\n",
                 {"test.toml:4:", "devices[0].kind", "hid, camera"});
  expect_problem("[[devices]]\nvid = 1\npid = 1\nkind = \"hid\"\nname = \"x\"\ncolour = 3\n",
                 {"test.toml:6:", "devices[0].colour", "unknown key"});
  expect_problem("source = 3\n", {"test.toml:1:", "source", "must be a table"});
  expect_problem("[calibration]\nfile = \"/nonexistent/cal.json\"\n",
                 {"test.toml:2:", "calibration.file", "/nonexistent/cal.json", "cannot read"});
  // Syntax errors carry the parser's position.
  expect_problem("\n[network\nport = 1\n", {"test.toml:2:"});
}

TEST(Config, EveryProblemIsReportedAtOnce) {
  try {
    (void)parse_config("[network]\nport = 0\nlease_ms = 1\nbogus = 1\n", "multi.toml");
    FAIL();
  } catch (const ConfigError& e) {
    EXPECT_EQ(e.problems().size(), 3u) << e.what();
  }
}

TEST(Config, CalibrationFileMustBeJson) {
  TempDir dir;
  dir.write("bad.json", "{ not json");
  const std::string path = dir.write("t.toml", "[calibration]\nfile = \"bad.json\"\n");
  try {
    (void)load_config(path);
    FAIL();
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find(path + ":2: calibration.file"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("not a JSON document"), std::string::npos) << e.what();
  }
}

TEST(Config, MissingFileIsNamed) {
  try {
    (void)load_config("/nonexistent/trackerd.toml");
    FAIL();
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/trackerd.toml"), std::string::npos);
  }
}

TEST(Config, CommandLineOverridesTheFile) {
  DaemonConfig c = parse_config("[source]\nrate = 500\nseed = 9\n[network]\nport = 47900\nlease_ms = 3000\n", "f.toml");
  CliOverrides cli;
  cli.port = 48000;
  cli.display = protocol::parse_display_geometry("800x600@300x200mm,500mm");
  cli.control_dir = "/srv/recordings";
  apply_overrides(c, cli);
  EXPECT_EQ(c.network.port, 48000);      // flag wins
  EXPECT_EQ(c.network.lease_ms, 3000u);  // file value kept where no flag was given
  EXPECT_EQ(c.source.rate_hz, 500);
  EXPECT_EQ(c.source.seed, 9u);
  ASSERT_TRUE(c.display.has_value());
  EXPECT_EQ(c.display->width_px, 800u);
  EXPECT_EQ(c.network.control_dir, "/srv/recordings");
  // And with no file at all, flags apply to the defaults.
  DaemonConfig d;
  CliOverrides only_rate;
  only_rate.rate_hz = 1000;
  apply_overrides(d, only_rate);
  EXPECT_EQ(d.source.rate_hz, 1000);
  EXPECT_EQ(d.network.port, protocol::kDefaultPort);
}

TEST(Config, ReloadSeparatesLiveChangesFromRestartOnes) {
  const DaemonConfig a = parse_config("[network]\nport = 47900\nlease_ms = 3000\n", "a.toml");
  const DaemonConfig b = parse_config(
      "[network]\nport = 47901\nlease_ms = 2000\ncontrol_allow = [\"10.0.0.0/8\"]\ncontrol_socket = \"/run/x.sock\"\n"
      "[source]\nrate = 100\n"
      "[display]\nwidth_px = 800\nheight_px = 600\nwidth_mm = 300\nheight_mm = 200\ndistance_mm = 500\n",
      "b.toml");
  const ConfigChanges ch = diff(a, b);
  const auto has = [](const std::vector<std::string>& v, const std::string& prefix) {
    for (const auto& s : v) {
      if (s.rfind(prefix, 0) == 0) return true;
    }
    return false;
  };
  EXPECT_TRUE(has(ch.live, "network.lease_ms 3000 -> 2000"));
  EXPECT_FALSE(has(ch.live, "network.control_allow")) << "ignored since issue 23: not reported as applied";
  EXPECT_TRUE(has(ch.live, "display"));
  EXPECT_TRUE(has(ch.needs_restart, "network.port 47900 -> 47901"));
  EXPECT_TRUE(has(ch.needs_restart, "source.rate"));
  EXPECT_TRUE(has(ch.needs_restart, "network.control_socket (the default) -> /run/x.sock"));
  EXPECT_FALSE(has(ch.live, "network.port"));
  const DaemonConfig adopted = adopt_live(a, b);
  EXPECT_EQ(adopted.network.port, 47900);  // kept
  EXPECT_EQ(adopted.network.control_socket, "");  // kept: the socket is opened once
  EXPECT_EQ(adopted.source.rate_hz, a.source.rate_hz);
  EXPECT_EQ(adopted.network.lease_ms, 2000u);  // applied
  EXPECT_TRUE(adopted.display.has_value());
  EXPECT_TRUE(diff(a, a).live.empty());
  EXPECT_TRUE(diff(a, a).needs_restart.empty());
  const DaemonConfig gbt = parse_config("[classifier]\nmethod = \"gbt\"\n", "g.toml");
  const DaemonConfig no_pso = parse_config("[classifier]\nmethod = \"gbt\"\npso = \"none\"\n", "n.toml");
  EXPECT_TRUE(has(diff(gbt, no_pso).live, "classifier.pso separate -> none"));
  EXPECT_EQ(adopt_live(gbt, no_pso).classifier.pso, "none");
  const DaemonConfig weighed = parse_config("[classifier]\nmethod = \"gbt\"\npursuit_weight = 2.5\n", "w.toml");
  EXPECT_TRUE(has(diff(gbt, weighed).live, "classifier.pursuit_weight 0 -> 2.5"));
  EXPECT_EQ(adopt_live(gbt, weighed).classifier.pursuit_weight, 2.5);
}

TEST(Config, EyePipelineTable) {
  const DaemonConfig c = parse_config(
      "[source]\nspec = \"synthetic-eye\"\n[eye]\nside = \"left\"\nleds = \"-8,0;8,0\"\npupil_downscale = 4\n"
      "pupil_roi = false\nsynthetic_width = 640\nsynthetic_height = 480\nsynthetic_hard = true\n",
      "eye.toml");
  EXPECT_EQ(c.eye.side, "left");
  EXPECT_EQ(c.eye.leds, "-8,0;8,0");
  EXPECT_EQ(c.eye.pupil_downscale, 4);
  EXPECT_FALSE(c.eye.pupil_roi);
  EXPECT_EQ(c.eye.synthetic_width, 640u);
  EXPECT_EQ(c.eye.synthetic_height, 480u);
  EXPECT_TRUE(c.eye.synthetic_hard);
  EXPECT_EQ(parse_config(to_toml(c), "printed.toml").eye, c.eye);
  EXPECT_EQ(DaemonConfig{}.eye.side, "right");
  EXPECT_EQ(DaemonConfig{}.source.rate_hz, 0) << "0: the source's own default rate";
  EXPECT_EQ(parse_config(to_toml(DaemonConfig{}), "d.toml").source, DaemonConfig{}.source);

  expect_problem("[eye]\nside = \"middle\"\n", {"test.toml:2:", "eye.side", "left, right"});
  expect_problem("[eye]\npupil_downscale = 3\n", {"test.toml:2:", "eye.pupil_downscale", "1, 2, 4"});
  expect_problem("[eye]\npupil_downscale = 8\n", {"test.toml:2:", "eye.pupil_downscale", "1..4"});
  expect_problem("[eye]\nsynthetic_width = 10\n", {"test.toml:2:", "eye.synthetic_width", "32..4096"});
  expect_problem("[eye]\nleds = 2\n", {"test.toml:2:", "eye.leds", "must be a string"});
  expect_problem("[eye]\nglints = 2\n", {"test.toml:2:", "eye.glints", "unknown key", "pupil_roi"});

  CliOverrides cli;
  cli.eye_side = "left";
  cli.synthetic_size = std::pair{std::uint32_t{160}, std::uint32_t{120}};
  cli.pupil_roi = false;
  DaemonConfig d;
  apply_overrides(d, cli);
  EXPECT_EQ(d.eye.side, "left");
  EXPECT_EQ(d.eye.synthetic_width, 160u);
  EXPECT_FALSE(d.eye.pupil_roi);
  EXPECT_EQ(d.eye.pupil_downscale, 2);  // not given: the default

  // The source is built once: eye settings need a restart.
  const ConfigChanges ch = diff(DaemonConfig{}, d);
  ASSERT_EQ(ch.needs_restart.size(), 4u);
  EXPECT_EQ(ch.needs_restart[0], "eye.side right -> left");
  EXPECT_TRUE(ch.live.empty());
  EXPECT_EQ(adopt_live(DaemonConfig{}, d).eye, DaemonConfig{}.eye);
}

TEST(Cidr, ParsesAndMatches) {
  const auto lo = protocol::parse_cidr("127.0.0.0/8");
  EXPECT_TRUE(lo.contains(0x7F000001));
  EXPECT_TRUE(lo.contains(0x7FFFFFFF));
  EXPECT_FALSE(lo.contains(0x80000000));
  const auto lan = protocol::parse_cidr("192.168.1.0/24");
  EXPECT_TRUE(lan.contains(0xC0A80114));
  EXPECT_FALSE(lan.contains(0xC0A80214));
  const auto host = protocol::parse_cidr("10.1.2.3");
  EXPECT_EQ(host.prefix, 32);
  EXPECT_TRUE(host.contains(0x0A010203));
  EXPECT_FALSE(host.contains(0x0A010204));
  const auto all = protocol::parse_cidr("0.0.0.0/0");
  EXPECT_TRUE(all.contains(0));
  EXPECT_TRUE(all.contains(0xFFFFFFFF));
  EXPECT_EQ(protocol::parse_cidr("10.0.0.0/8").to_string(), "10.0.0.0/8");
  EXPECT_TRUE(protocol::allowed({lo, lan}, 0xC0A80101));
  EXPECT_FALSE(protocol::allowed({}, 0x7F000001));
  for (const char* bad : {"", "127.0.0.1/", "127.0.0.1/33", "256.0.0.0/8", "1.2.3/8", "a.b.c.d/8", "10.0.0.0/x",
                          "10.1.0.0/8", " 10.0.0.0/8", "10. 0.0.0/8", "10.+0.0.0/8", "10.0.0.0/8 ", "10.0.0.0/-1"}) {
    EXPECT_THROW((void)protocol::parse_cidr(bad), std::invalid_argument) << bad;
  }
}

// [lsl]: the outlet where this build has liblsl; refused with the reason where it has none, so
// --check-config says so before the service fails to start.
TEST(Config, LslOutletIsAcceptedOnlyWhereLiblslIsBuiltIn) {
  const std::string text = "[lsl]\noutlet = true\nname = \"lab-a\"\n";
  if (fovea::trackerd::lsl_available()) {
    const DaemonConfig c = parse_config(text, "lsl.toml");
    EXPECT_TRUE(c.lsl.outlet);
    EXPECT_EQ(c.lsl.name, "lab-a");
    EXPECT_EQ(parse_config(to_toml(c), "again").lsl, c.lsl) << to_toml(c);
  } else {
    try {
      parse_config(text, "lsl.toml");
      ADD_FAILURE() << "a build without liblsl accepted [lsl] outlet = true";
    } catch (const ConfigError& e) {
      EXPECT_NE(std::string(e.what()).find("lsl.toml:2: lsl.outlet"), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("without liblsl"), std::string::npos) << e.what();
    }
  }
  EXPECT_THROW(parse_config("[lsl]\nname = \"\"\n", "empty.toml"), ConfigError);
  EXPECT_EQ(parse_config("", "none").lsl, LslConfig{}) << "off by default";
}
