// SPDX-License-Identifier: Apache-2.0
#include "service/systemd_notify.h"

#include <systemd/sd-daemon.h>

#include <cstdlib>
#include <ctime>

namespace fovea::trackerd::service {

namespace {
std::int64_t monotonic_us() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return std::int64_t{ts.tv_sec} * 1'000'000 + ts.tv_nsec / 1000;
}
}  // namespace

SystemdNotifier::SystemdNotifier() {
  const char* socket = std::getenv("NOTIFY_SOCKET");
  enabled_ = socket != nullptr && socket[0] != '\0';
  std::uint64_t usec = 0;
  if (sd_watchdog_enabled(0, &usec) > 0 && usec > 0) {
    watchdog_interval_ns_ = static_cast<std::int64_t>(usec) * 1000 / 2;
  }
}

void SystemdNotifier::send(const std::string& text) {
  if (enabled_) sd_notify(0, text.c_str());
}

void SystemdNotifier::ready(const std::string& s) { send("READY=1\nSTATUS=" + s); }
void SystemdNotifier::status(const std::string& s) { send("STATUS=" + s); }
void SystemdNotifier::reloading() {
  send("RELOADING=1\nMONOTONIC_USEC=" + std::to_string(monotonic_us()) + "\nSTATUS=reloading configuration");
}
void SystemdNotifier::reloaded(const std::string& s) { send("READY=1\nSTATUS=" + s); }
void SystemdNotifier::stopping() { send("STOPPING=1\nSTATUS=stopping"); }

void SystemdNotifier::watchdog_tick(std::int64_t now_ns) {
  if (watchdog_interval_ns_ == 0 || now_ns < next_ping_ns_) return;
  next_ping_ns_ = now_ns + watchdog_interval_ns_;
  sd_notify(0, "WATCHDOG=1");
}

}  // namespace fovea::trackerd::service
