// SPDX-License-Identifier: Apache-2.0
#pragma once
// sd_notify(3) for fovea-trackerd under systemd (Type=notify): READY, STATUS, RELOADING, STOPPING
// and watchdog pings. Every call is a no-op when the process was not started by systemd with a
// notification socket (NOTIFY_SOCKET unset), so the daemon runs the same from a shell.
#include <cstdint>
#include <string>

namespace fovea::trackerd::service {

class SystemdNotifier {
 public:
  SystemdNotifier();  // reads NOTIFY_SOCKET and WATCHDOG_USEC/WATCHDOG_PID (sd_watchdog_enabled)

  bool enabled() const { return enabled_; }
  // 0 when systemd expects no watchdog pings; otherwise the interval between pings (half of
  // WatchdogSec, as sd_watchdog_enabled(3) recommends).
  std::int64_t watchdog_interval_ns() const { return watchdog_interval_ns_; }

  void ready(const std::string& status);     // READY=1 + STATUS=
  void status(const std::string& status);    // STATUS=
  void reloading();                          // RELOADING=1 + MONOTONIC_USEC=
  void reloaded(const std::string& status);  // READY=1 after a reload
  void stopping();                           // STOPPING=1

  // Sends WATCHDOG=1 when the interval has passed since the last ping. Call it from the loop whose
  // progress the watchdog should vouch for (the publishing loop): a stuck loop stops the pings.
  void watchdog_tick(std::int64_t now_ns);
  // Sends STATUS=<make()> at most once a second.
  template <typename F>
  void status_tick(std::int64_t now_ns, F&& make) {
    if (!enabled_ || now_ns < next_status_ns_) return;
    next_status_ns_ = now_ns + 1'000'000'000;
    status(make());
  }

 private:
  void send(const std::string& text);
  bool enabled_ = false;
  std::int64_t watchdog_interval_ns_ = 0;
  std::int64_t next_ping_ns_ = 0;
  std::int64_t next_status_ns_ = 0;
};

}  // namespace fovea::trackerd::service
