#pragma once
// Reads the next item of a sequence on a second thread while the caller works on the current one:
// a run of `hmap map` or `hmap slam` decodes scan k + 1 while scan k is integrated, so that the
// whole process costs little more than its integration (issue 19, "the whole run").

#include <cstddef>
#include <functional>
#include <future>
#include <stdexcept>
#include <utility>

namespace hmap {

/// Whether the next item is read on a second thread. Worth it where reading is decoding (a bag's
/// compressed chunks and CDR clouds: `hmap map` on balm_os0's MCAP 1.97 → 1.82 s); a KITTI .bin is
/// a copy, and a third thread beside the two integrating made that run slower (0.62 → 0.68 s).
enum class ReadAhead { kNo, kYes };

/// Items 0 .. count − 1 of `read`, taken in order by next(); with ReadAhead::kYes the next item is
/// read on a second thread while the caller works on the current one (at most one ahead).
/// `read` is called once per index, in order, never twice at once (it may keep state, as a bag
/// reader does). An exception `read` throws for item k is thrown by the next() that asks for k.
template <class T>
class Prefetcher {
 public:
  using Read = std::function<T(std::size_t)>;

  Prefetcher(std::size_t count, Read read, ReadAhead ahead = ReadAhead::kYes)
      : count_(count), read_(std::move(read)), ahead_(ahead) {
    launch(0);
  }
  Prefetcher(const Prefetcher&) = delete;
  Prefetcher& operator=(const Prefetcher&) = delete;
  /// Waits for a read still running (a run that stops early must not leave a thread reading).
  ~Prefetcher() {
    if (pending_.valid()) pending_.wait();
  }

  [[nodiscard]] bool done() const { return next_ >= count_; }

  /// The next item: waits for its read, then starts the one after it.
  T next() {
    if (done()) throw std::out_of_range("Prefetcher::next after the last item");
    if (ahead_ == ReadAhead::kNo) return read_(next_++);
    T item = pending_.get();  // rethrows the read's exception
    ++next_;
    launch(next_);
    return item;
  }

 private:
  void launch(std::size_t k) {
    if (k >= count_ || ahead_ == ReadAhead::kNo) return;
    pending_ = std::async(std::launch::async, [this, k] { return read_(k); });
  }

  std::size_t count_;
  std::size_t next_ = 0;
  Read read_;
  ReadAhead ahead_;
  std::future<T> pending_;
};

}  // namespace hmap
