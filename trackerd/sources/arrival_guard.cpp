// SPDX-License-Identifier: Apache-2.0
#include "sources/arrival_guard.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>

namespace fovea::trackerd::net {

namespace {

bool usable_rate(double hz) { return std::isfinite(hz) && hz > 0; }

std::string rate_text(double hz) {
  char text[32];
  std::snprintf(text, sizeof text, "%.0f", hz);
  return text;
}

std::string declared_text(double hz) {
  char text[32];
  std::snprintf(text, sizeof text, "%g", hz);
  return text;
}

}  // namespace

ArrivalGuard::ArrivalGuard(double nominal_rate_hz)
    : nominal_rate_hz_(usable_rate(nominal_rate_hz) ? nominal_rate_hz : 0),
      capacity_(std::max(kMinBurst, nominal_rate_hz_)),
      refill_hz_(kFloodFactor * nominal_rate_hz_),
      tokens_(capacity_) {}

void ArrivalGuard::set_name(std::string name) {
  std::lock_guard lock(mutex_);
  name_ = std::move(name);
}

ArrivalGuard::Admission ArrivalGuard::admit(std::int64_t receive_ns) {
  Admission a;
  if (refill_hz_ <= 0) return a;
  std::lock_guard lock(mutex_);
  // Refill for the time since the last arrival (a clock that stepped back refills nothing).
  if (seen_ && receive_ns > last_arrival_ns_) {
    tokens_ = std::min(capacity_, tokens_ + static_cast<double>(receive_ns - last_arrival_ns_) * 1e-9 * refill_hz_);
  }
  seen_ = true;
  last_arrival_ns_ = std::max(last_arrival_ns_, receive_ns);
  if (flooding_ && receive_ns - last_drop_ns_ >= kFloodQuietNs) end_flood(receive_ns);
  a.within_pace = tokens_ >= capacity_;
  if (a.within_pace) {
    paced_ns_ = receive_ns;
    since_paced_ = 0;
  }
  ++since_paced_;
  if (flooding_) ++flood_arrivals_;
  if (tokens_ >= 1) {
    tokens_ -= 1;
  } else {
    a.keep = false;
    ++stats_.dropped;
    last_drop_ns_ = receive_ns;
    if (!flooding_) {
      begin_flood(receive_ns);
      a.flood_began = true;
    }
    ++flood_dropped_;
  }
  a.flooding = flooding_;
  if (flooding_) warn_if_due(receive_ns);
  return a;
}

void ArrivalGuard::poll(std::int64_t now_ns) {
  if (refill_hz_ <= 0) return;
  std::lock_guard lock(mutex_);
  if (!flooding_) return;
  if (now_ns - last_drop_ns_ >= kFloodQuietNs) {
    end_flood(now_ns);
  } else {
    warn_if_due(now_ns);
  }
}

void ArrivalGuard::count_future(std::int64_t mapped_ns, std::int64_t receive_ns) {
  // mapped_ns > receive_ns: their difference fits in 64 bits unsigned; a larger lead reads as the most.
  const std::uint64_t lead = static_cast<std::uint64_t>(mapped_ns) - static_cast<std::uint64_t>(receive_ns);
  const auto lead_ns = static_cast<std::int64_t>(std::min<std::uint64_t>(lead, INT64_MAX));
  std::lock_guard lock(mutex_);
  ++stats_.future;
  stats_.max_lead_ns = std::max(stats_.max_lead_ns, lead_ns);
}

// The flood is measured from the last arrival that found the bucket full: the burst that emptied it
// is the flood's beginning.
void ArrivalGuard::begin_flood(std::int64_t now_ns) {
  flooding_ = true;
  warned_ = false;
  ++stats_.floods;
  flood_start_ns_ = now_ns;
  flood_from_ns_ = paced_ns_;
  flood_arrivals_ = since_paced_;
  flood_dropped_ = 0;
}

double ArrivalGuard::flood_rate_hz() const {
  // At least a millisecond: a backlog read in one go arrives all at once.
  const std::int64_t span_ns = std::max<std::int64_t>(last_arrival_ns_ - flood_from_ns_, 1'000'000);
  return static_cast<double>(flood_arrivals_) / (static_cast<double>(span_ns) * 1e-9);
}

void ArrivalGuard::warn_if_due(std::int64_t now_ns) {
  if (warned_ || now_ns - flood_start_ns_ < kWarnAfterNs) return;
  warned_ = true;
  spdlog::warn("{}: floods: {} samples/s arriving against {} Hz declared (more than {}x); publishing at most {}/s, "
               "the first to arrive within that pace, the rest dropped; while it floods its samples are stamped on "
               "arrival and their timestamps teach its clock nothing",
               name_, rate_text(flood_rate_hz()), declared_text(nominal_rate_hz_), declared_text(kFloodFactor),
               rate_text(refill_hz_));
}

void ArrivalGuard::end_flood(std::int64_t now_ns) {
  warn_if_due(now_ns);
  flooding_ = false;
  spdlog::info("{}: the flood ended: {:.1f} s long, {} samples dropped over the cap of {}/s ({} in all floods)", name_,
               static_cast<double>(last_drop_ns_ - flood_from_ns_) * 1e-9, flood_dropped_, rate_text(refill_hz_),
               stats_.dropped);
}

ArrivalGuard::Stats ArrivalGuard::stats() const {
  std::lock_guard lock(mutex_);
  Stats s = stats_;
  s.flooding = flooding_;
  s.arrival_rate_hz = flooding_ ? flood_rate_hz() : 0;
  return s;
}

std::string ArrivalGuard::status() const {
  const Stats s = stats();
  std::string out;
  if (s.flooding) {
    out += ", FLOODING: " + rate_text(s.arrival_rate_hz) + "/s against " + declared_text(nominal_rate_hz_) +
           " Hz declared, publishing at most " + rate_text(refill_hz_) + "/s";
  }
  if (s.floods > 0) {
    out += ", " + std::to_string(s.dropped) + " dropped over the " + declared_text(kFloodFactor) + "x cap in " +
           std::to_string(s.floods) + (s.floods == 1 ? " flood" : " floods");
  }
  if (s.future > 0) {
    char text[128];
    std::snprintf(text, sizeof text, ", %llu from the future (up to %.1f ms ahead; stamped on arrival)",
                  static_cast<unsigned long long>(s.future), static_cast<double>(s.max_lead_ns) * 1e-6);
    out += text;
  }
  return out;
}

}  // namespace fovea::trackerd::net
