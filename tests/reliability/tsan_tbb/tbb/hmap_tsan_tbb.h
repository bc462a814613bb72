#pragma once
// The part of TBB that hmap uses (blocked_range, parallel_for, parallel_invoke,
// enumerable_thread_specific), on plain std::thread, for the ThreadSanitizer build only
// (HMAP_TSAN=ON puts this folder first on the include path).
//
// Why: Debian's libtbb is not built with TSan, so the hand-over of every task between threads
// (atomics inside libtbb.so) is invisible to it and each parallel_for is reported as a race
// between the code before it and its body. Thread creation and join are visible: on these, TSan
// checks hmap's own code (the bodies running at the same time, the branches of parallel_invoke,
// the per-thread buffers) and nothing else. Every call runs on kThreads threads at once, more than
// the machine's cores, so that bodies interleave.

#include <algorithm>
#include <atomic>
#include <condition_variable>
#include <cstddef>
#include <deque>
#include <exception>
#include <functional>
#include <mutex>
#include <thread>
#include <utility>
#include <vector>

namespace tbb {

namespace hmap_tsan {

inline constexpr std::size_t kThreads = 4;

/// kThreads - 1 threads kept for the whole run, so that enumerable_thread_specific sees the same
/// threads call after call (as with TBB's fixed pool; hmap keeps a buffer per thread). Work is
/// handed over under a mutex and a condition variable, which TSan sees.
class Pool {
 public:
  static Pool& instance() {
    static Pool pool;
    return pool;
  }
  Pool(const Pool&) = delete;
  Pool& operator=(const Pool&) = delete;
  ~Pool() {
    {
      const std::lock_guard<std::mutex> lock(mutex_);
      stop_ = true;
    }
    wake_.notify_all();
    for (auto& worker : workers_) worker.join();
  }

  /// Runs job(t) for t in [1, n) on the pool's workers; false (nothing run) when the pool is busy
  /// (a parallel call inside a parallel call).
  bool try_run(std::size_t n, const std::function<void(std::size_t)>& job) {
    std::unique_lock<std::mutex> lock(mutex_);
    if (job_ != nullptr) return false;
    job_ = &job;
    jobs_ = n - 1;
    taken_ = 0;
    done_ = 0;
    wake_.notify_all();
    return true;
  }
  void wait() {
    std::unique_lock<std::mutex> lock(mutex_);
    finished_.wait(lock, [&] { return done_ == jobs_; });
    job_ = nullptr;
  }

 private:
  Pool() {
    for (std::size_t t = 1; t < kThreads; ++t) workers_.emplace_back([this] { work(); });
  }
  void work() {
    std::unique_lock<std::mutex> lock(mutex_);
    for (;;) {
      wake_.wait(lock, [&] { return stop_ || (job_ != nullptr && taken_ < jobs_); });
      if (stop_) return;
      const std::size_t t = 1 + taken_++;
      const auto* job = job_;
      lock.unlock();
      (*job)(t);
      lock.lock();
      if (++done_ == jobs_) finished_.notify_all();
    }
  }

  std::mutex mutex_;
  std::condition_variable wake_;
  std::condition_variable finished_;
  std::vector<std::thread> workers_;
  const std::function<void(std::size_t)>* job_ = nullptr;
  std::size_t jobs_ = 0;
  std::size_t taken_ = 0;
  std::size_t done_ = 0;
  bool stop_ = false;
};

/// Runs task(t) for t in [0, n) on n threads at once (the caller runs t = 0; n <= kThreads);
/// rethrows the first exception after all have ended, as TBB does.
template <typename Task>
void run_threads(std::size_t n, const Task& task) {
  std::exception_ptr error;
  std::mutex error_mutex;
  const std::function<void(std::size_t)> guarded = [&](std::size_t t) {
    try {
      task(t);
    } catch (...) {
      const std::lock_guard<std::mutex> lock(error_mutex);
      if (!error) error = std::current_exception();
    }
  };
  if (n > 1 && Pool::instance().try_run(n, guarded)) {
    guarded(0);
    Pool::instance().wait();
  } else {  // nested: threads of its own
    std::vector<std::thread> threads;
    for (std::size_t t = 1; t < n; ++t) threads.emplace_back(guarded, t);
    guarded(0);
    for (auto& thread : threads) thread.join();
  }
  if (error) std::rethrow_exception(error);
}

}  // namespace hmap_tsan

template <typename Value>
class blocked_range {
 public:
  using const_iterator = Value;
  blocked_range(Value begin, Value end, std::size_t grainsize = 1)
      : begin_(begin), end_(end), grainsize_(grainsize == 0 ? 1 : grainsize) {}
  [[nodiscard]] Value begin() const { return begin_; }
  [[nodiscard]] Value end() const { return end_; }
  [[nodiscard]] std::size_t size() const { return static_cast<std::size_t>(end_ - begin_); }
  [[nodiscard]] bool empty() const { return !(begin_ < end_); }
  [[nodiscard]] std::size_t grainsize() const { return grainsize_; }

 private:
  Value begin_;
  Value end_;
  std::size_t grainsize_;
};

/// The range cut into pieces of grainsize, taken by kThreads threads from a shared counter.
template <typename Value, typename Body>
void parallel_for(const blocked_range<Value>& range, const Body& body) {
  if (range.empty()) return;
  const std::size_t grain = range.grainsize();
  const std::size_t pieces = (range.size() + grain - 1) / grain;
  std::atomic<std::size_t> next{0};
  hmap_tsan::run_threads(std::min(hmap_tsan::kThreads, pieces), [&](std::size_t) {
    for (std::size_t piece = next++; piece < pieces; piece = next++) {
      const Value begin = range.begin() + static_cast<Value>(piece * grain);
      const Value end = piece + 1 == pieces ? range.end() : begin + static_cast<Value>(grain);
      body(blocked_range<Value>(begin, end, grain));
    }
  });
}

/// The functions on up to kThreads threads at once (taken from a shared counter).
template <typename... Functions>
void parallel_invoke(const Functions&... functions) {
  const std::vector<std::function<void()>> tasks = {std::function<void()>(functions)...};
  std::atomic<std::size_t> next{0};
  hmap_tsan::run_threads(std::min(hmap_tsan::kThreads, tasks.size()), [&](std::size_t) {
    for (std::size_t t = next++; t < tasks.size(); t = next++) tasks[t]();
  });
}

/// One T per thread that calls local(), created on first call; iterating visits them all (only
/// when no parallel call is running, as with TBB).
template <typename T>
class enumerable_thread_specific {
 public:
  using iterator = typename std::deque<T>::iterator;
  using const_iterator = typename std::deque<T>::const_iterator;

  T& local() {
    const std::lock_guard<std::mutex> lock(mutex_);
    const auto id = std::this_thread::get_id();
    for (std::size_t k = 0; k < owners_.size(); ++k) {
      if (owners_[k] == id) return values_[k];
    }
    owners_.push_back(id);
    return values_.emplace_back();
  }
  iterator begin() { return values_.begin(); }
  iterator end() { return values_.end(); }
  const_iterator begin() const { return values_.begin(); }
  const_iterator end() const { return values_.end(); }
  [[nodiscard]] std::size_t size() const { return values_.size(); }
  void clear() {
    owners_.clear();
    values_.clear();
  }

 private:
  std::mutex mutex_;
  std::vector<std::thread::id> owners_;
  std::deque<T> values_;  // stable references
};

}  // namespace tbb
