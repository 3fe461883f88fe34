#pragma once
/// Bounded multi-producer multi-consumer FIFO between threads (STYLE.md section 3): tracking ->
/// local mapping -> loop closing hand keyframes on through these.
///
///   while (std::optional<std::shared_ptr<KeyFrame>> kf = input_.pop()) { ... }  // ends on close()
///
/// push() blocks while the queue is full, pop() while it is empty; close() wakes every waiter.
/// After close(), push() refuses new items but pop() still drains what is queued, then returns
/// std::nullopt. Thread-safe; one mutex and two condition variables inside, never held while the
/// caller's code runs.
#include <condition_variable>
#include <cstddef>
#include <deque>
#include <mutex>
#include <optional>
#include <utility>

#include "ltlo/core/assert.h"

namespace ltlo {

template <typename T>
class BlockingQueue {
 public:
  /// `capacity` >= 1 items; a full queue makes push() wait (back-pressure on the producer).
  explicit BlockingQueue(std::size_t capacity) : capacity_(capacity) {
    LTLO_ASSERT(capacity >= 1, "BlockingQueue capacity must be at least 1, got " << capacity);
  }
  BlockingQueue(const BlockingQueue&) = delete;
  BlockingQueue& operator=(const BlockingQueue&) = delete;

  /// Appends `value`, waiting while the queue is full. Returns false (and drops the value) when
  /// the queue is or becomes closed before there is room.
  bool push(T value) {
    std::unique_lock<std::mutex> lock(mutex_);
    not_full_.wait(lock, [&] { return closed_ || items_.size() < capacity_; });
    if (closed_) return false;
    items_.push_back(std::move(value));
    lock.unlock();
    not_empty_.notify_one();
    return true;
  }

  /// Appends `value` only if there is room now and the queue is open; never waits.
  bool tryPush(T value) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (closed_ || items_.size() >= capacity_) return false;
      items_.push_back(std::move(value));
    }
    not_empty_.notify_one();
    return true;
  }

  /// Removes the oldest item, waiting while the queue is empty and open. std::nullopt once the
  /// queue is closed and drained.
  std::optional<T> pop() {
    std::unique_lock<std::mutex> lock(mutex_);
    not_empty_.wait(lock, [&] { return closed_ || !items_.empty(); });
    return takeFrontLocked(lock);
  }

  /// Removes the oldest item if there is one now; never waits.
  std::optional<T> tryPop() {
    std::unique_lock<std::mutex> lock(mutex_);
    return takeFrontLocked(lock);
  }

  /// Refuses further pushes and wakes all waiting producers and consumers. Idempotent.
  void close() {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      closed_ = true;
    }
    not_full_.notify_all();
    not_empty_.notify_all();
  }

  bool closed() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return closed_;
  }
  /// Items queued at this instant (a snapshot; other threads may change it right after).
  std::size_t size() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return items_.size();
  }
  std::size_t capacity() const { return capacity_; }

 private:
  std::optional<T> takeFrontLocked(std::unique_lock<std::mutex>& lock) {
    if (items_.empty()) return std::nullopt;
    std::optional<T> front(std::move(items_.front()));
    items_.pop_front();
    lock.unlock();
    not_full_.notify_one();
    return front;
  }

  const std::size_t capacity_;
  mutable std::mutex mutex_;  // guards items_ and closed_
  std::condition_variable not_full_;
  std::condition_variable not_empty_;
  std::deque<T> items_;
  bool closed_ = false;
};

}  // namespace ltlo
