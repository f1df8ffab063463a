// SPDX-License-Identifier: Apache-2.0
#pragma once
// The kinds of gaze source fovea-trackerd can open, as one table: gpsd keeps its drivers in one
// array (drivers/drivers.c) and so do we. `--source`'s help, `--check-config`, the configuration's
// messages and the daemon all read this table; adding a source kind is one row in
// source_table.cpp plus the files that implement it (a GazeSource, source_api/gaze_source.h).
//
// A spec names its kind by its start: "synthetic", "replay:demo.fgr", "hid", "hid:046d:c52b",
// "camera:/dev/video0", "camera:usb:046d:0825", "video:eye.mp4". When several rows' prefixes fit a
// spec, the longest wins ("camera:usb:..." before "camera:...").
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "service/config.h"
#include "source_api/gaze_source.h"

namespace fovea::trackerd {

struct SourceKind {
  // What a spec of this kind is: `prefix` alone when `argument` is None ("synthetic"); `prefix`
  // then a non-empty argument when Required ("replay:" FILE); either when Optional ("hid", or
  // "hid:" VID:PID, written "hid" here).
  enum class Argument { None, Required, Optional };
  const char* prefix;
  Argument argument;
  const char* syntax;  // as lists and help show it: "replay:FILE"
  const char* help;    // what it is, a few words for --source's help: ".fgr or .csv recording"
  // What can be seen wrong with a spec of this kind without opening anything beyond the prefix rule
  // above: empty when usable, else a message naming the spec. nullptr: nothing more to check.
  std::string (*check)(const std::string& spec);
  // Builds the source from the configuration (its `source.spec` is of this kind); throws
  // std::invalid_argument / std::runtime_error naming the spec and what is wrong.
  std::unique_ptr<GazeSource> (*make)(const service::DaemonConfig& config, std::int64_t start_time_ns);
};

// Every kind this build can open, in the order lists and help show them.
std::span<const SourceKind> source_kinds();

// The row whose prefix fits `spec` (the longest), or nullptr.
const SourceKind* find_source_kind(const std::string& spec);

// "synthetic, synthetic-eye, replay:FILE, ...": every row's syntax, for messages.
std::string source_kind_list();

// `--source`'s help: each row's syntax and help, then what cameras and videos publish.
std::string source_help();

// Empty when this build has a source of the kind `spec` names; otherwise a message naming the
// spec and the kinds it supports. (--check-config uses it without opening anything.)
std::string check_source_spec(const std::string& spec);

// The eye pipeline's settings ([eye], --eye, --leds, ...) that only the eye module can check (the
// LED layout's syntax); one "eye.KEY: what is wrong" per problem, empty when all are usable.
std::vector<std::string> check_eye_config(const service::EyeConfig& eye);

// Builds the source named by `config.source.spec` through its row; throws std::invalid_argument /
// std::runtime_error with a message naming the spec and what is wrong.
std::unique_ptr<GazeSource> make_source(const service::DaemonConfig& config, std::int64_t start_time_ns);

}  // namespace fovea::trackerd
