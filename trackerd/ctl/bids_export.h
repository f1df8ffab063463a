// SPDX-License-Identifier: Apache-2.0
#pragma once
// BIDS export of a gaze recording (issue 26 item 6): the .fgr's samples as an eye-tracking
// physiological recording (BIDS 1.10, "Physiological recordings" / "Eye-tracking"), its eye-movement
// events and markers as physioevents, its markers as task events, in a BIDS dataset directory.
// Files, columns and fields: protocol/RECORDING.md, "BIDS export".
#include <cstddef>
#include <string>
#include <vector>

#include "fovea/protocol/recording.h"

namespace fovea::ctl {

inline constexpr const char* kBidsVersion = "1.10.0";

struct BidsOptions {
  std::string dataset_dir;       // the dataset's root (created if missing)
  std::string subject;           // sub-<label>: letters and digits
  std::string task;              // task-<label>
  std::string session;           // ses-<label>; empty: none
  std::string run;               // run-<index>: digits; empty: none
  std::string recording = "eye1";  // recording-<label> (REQUIRED for eye-tracking; eye1 RECOMMENDED)
  std::string generator_version;   // for dataset_description.json's GeneratedBy
};

struct BidsResult {
  std::vector<std::string> written;  // every file created, dataset root first where it was created
  std::string scans_tsv;             // the scans.tsv the acquisition time went to (created or appended)
  std::size_t samples = 0, valid_samples = 0;
  std::size_t events = 0;            // eye-movement events (final, ended ones)
  std::size_t unfinished_events = 0; // started but never ended in the recording: left out
  std::size_t markers = 0;
  double sampling_frequency = 0;
  bool measured_rate = false;        // the header had no nominal rate: measured from the samples
};

// Empty when `label` is a valid BIDS label (one or more ASCII letters or digits); otherwise why not,
// naming `what` (e.g. "--subject").
std::string bids_label_error(const std::string& what, const std::string& label);

// The file names (relative to the dataset root) the export writes for these options, scans.tsv and
// dataset_description.json not included.
std::vector<std::string> bids_output_names(const BidsOptions& o);

// Writes the export. Refuses (std::runtime_error naming the path) if any output file already exists,
// before writing anything; a file that appears meanwhile is not replaced either (each file is linked
// into place, never renamed over). dataset_description.json is written only where none exists; the
// session's scans.tsv is created, or gets one row appended. On failure the files this call created
// are removed again. Throws std::runtime_error on a bad label or a recording without samples.
BidsResult export_bids(const protocol::Recording& rec, const BidsOptions& o);

// gzip (RFC 1952) of `data`, as zlib writes it. Throws std::runtime_error on a zlib failure.
std::string gzip_compress(const std::string& data);

}  // namespace fovea::ctl
