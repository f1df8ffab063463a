// SPDX-License-Identifier: Apache-2.0
#pragma once
// Hands control commands from the server's control thread to the publishing loop, which owns the
// daemon's state (recorder, configuration) and executes them between two samples. The caller
// waits for the result; a command the loop has not picked up within the timeout is withdrawn and
// reported as not executed, so a reply never claims something that did not (or did) happen.
// What a command submits is an action: slow work (reading a file) is done by the caller before it
// submits, so the loop only swaps in the result and publishing never waits on a client's file.
#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>

#include "fovea/protocol/messages.h"

namespace fovea::trackerd::service {

class CommandMailbox {
 public:
  using Action = std::function<protocol::ControlReply()>;

  // Control thread: queues `action` (the command `request`) and waits for the loop to run it.
  protocol::ControlReply submit(const protocol::ControlRequest& request, Action action, std::chrono::milliseconds timeout) {
    auto entry = std::make_shared<Entry>(Entry{request, std::move(action), std::nullopt});
    std::unique_lock lock(mutex_);
    if (closed_) return failed(request, "the daemon is stopping");
    queue_.push_back(entry);
    pending_.store(true);
    if (!cv_.wait_for(lock, timeout, [&] { return entry->reply.has_value() || closed_; })) {
      if (const auto it = std::find(queue_.begin(), queue_.end(), entry); it != queue_.end()) {
        queue_.erase(it);
        return failed(request, "the daemon is busy; not executed");
      }
      cv_.wait(lock, [&] { return entry->reply.has_value() || closed_; });  // running now: wait for it
    }
    if (entry->reply) return *entry->reply;
    return failed(request, "the daemon is stopping");
  }

  // Publishing loop: true when commands are waiting (cheap; checked between samples).
  bool pending() const { return pending_.load(std::memory_order_relaxed); }

  // Publishing loop: runs every queued command's action.
  void drain() {
    std::deque<std::shared_ptr<Entry>> work;
    {
      std::lock_guard lock(mutex_);
      work.swap(queue_);
      pending_.store(false);
    }
    for (auto& e : work) {
      protocol::ControlReply r = e->action();
      std::lock_guard lock(mutex_);
      e->reply = std::move(r);
      cv_.notify_all();
    }
  }

  // Publishing loop, on the way out: refuses what is queued and everything after.
  void close() {
    std::lock_guard lock(mutex_);
    closed_ = true;
    queue_.clear();
    pending_.store(false);
    cv_.notify_all();
  }

 private:
  struct Entry {
    protocol::ControlRequest request;
    Action action;
    std::optional<protocol::ControlReply> reply;
  };
  static protocol::ControlReply failed(const protocol::ControlRequest& r, const char* why) {
    protocol::ControlReply out{r.command, protocol::ControlResult::Failed, {}};
    out.message.value = why;
    return out;
  }
  std::mutex mutex_;
  std::condition_variable cv_;
  std::deque<std::shared_ptr<Entry>> queue_;
  std::atomic<bool> pending_{false};
  bool closed_ = false;
};

}  // namespace fovea::trackerd::service
