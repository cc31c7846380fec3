#pragma once

#include <algorithm>
#include <condition_variable>
#include <deque>
#include <mutex>
#include <vector>

#include "handlers/handlers.h"

namespace occgeo::service {

// A session without a socket: records what handlers send, for handler tests.
class FakeSession final : public SessionContext {
 public:
  explicit FakeSession(ServerCore& core) : core_(core) {}
  ServerCore& core() override { return core_; }
  SessionInfo& info() override { return info_; }
  void send(const v1::ServerMessage& message) override {
    const std::lock_guard lock(mutex_);
    sent_.push_back(message);
    arrived_.notify_all();
  }

  // The next message sent, waiting up to 5 s for handlers running on worker pools.
  std::optional<v1::ServerMessage> next() {
    std::unique_lock lock(mutex_);
    if (!arrived_.wait_for(lock, std::chrono::seconds(5), [&] { return !sent_.empty(); })) return std::nullopt;
    v1::ServerMessage message = std::move(sent_.front());
    sent_.pop_front();
    return message;
  }
  // The next message of the given kind, skipping others.
  std::optional<v1::ServerMessage> next_of(v1::ServerMessage::BodyCase kind) {
    for (int i = 0; i < 20; ++i) {
      auto message = next();
      if (!message) return std::nullopt;
      if (message->body_case() == kind) return message;
    }
    return std::nullopt;
  }
  // The first message of the given kind, waiting up to 5 s for it; messages of other kinds stay queued, in order (a
  // scan's ScanAck and the MotionCommand answering it may leave in either order: the ack waits for its fsync).
  std::optional<v1::ServerMessage> take_first_of(v1::ServerMessage::BodyCase kind) {
    std::unique_lock lock(mutex_);
    std::optional<v1::ServerMessage> found;
    arrived_.wait_for(lock, std::chrono::seconds(5), [&] {
      const auto it = std::find_if(sent_.begin(), sent_.end(), [&](const auto& m) { return m.body_case() == kind; });
      if (it == sent_.end()) return false;
      found = std::move(*it);
      sent_.erase(it);
      return true;
    });
    return found;
  }
  // Everything sent so far and not yet taken, without waiting (call after ServerCore::drain).
  std::vector<v1::ServerMessage> take_all() {
    const std::lock_guard lock(mutex_);
    std::vector<v1::ServerMessage> all(std::make_move_iterator(sent_.begin()), std::make_move_iterator(sent_.end()));
    sent_.clear();
    return all;
  }

 private:
  ServerCore& core_;
  SessionInfo info_;
  std::mutex mutex_;
  std::condition_variable arrived_;
  std::deque<v1::ServerMessage> sent_;
};

}  // namespace occgeo::service
