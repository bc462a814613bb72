#include "hmap/io/prefetch.hpp"

#include <gtest/gtest.h>

#include <atomic>
#include <mutex>
#include <stdexcept>
#include <thread>
#include <vector>

namespace hmap {
namespace {

TEST(Prefetcher, GivesEveryItemOnceInOrder) {
  std::mutex m;
  std::vector<std::size_t> calls;
  Prefetcher<std::size_t> p(5, [&](std::size_t k) {
    const std::lock_guard<std::mutex> lock(m);
    calls.push_back(k);
    return k * k;
  });
  std::vector<std::size_t> got;
  while (!p.done()) got.push_back(p.next());
  EXPECT_EQ(got, (std::vector<std::size_t>{0, 1, 4, 9, 16}));
  EXPECT_EQ(calls, (std::vector<std::size_t>{0, 1, 2, 3, 4}));
  EXPECT_THROW((void)p.next(), std::out_of_range);
}

TEST(Prefetcher, WithoutReadAheadEachItemIsReadWhenAskedFor) {
  std::vector<std::size_t> calls;
  Prefetcher<std::size_t> p(
      3, [&](std::size_t k) {
        calls.push_back(k);
        return k + 10;
      },
      ReadAhead::kNo);
  EXPECT_TRUE(calls.empty());
  EXPECT_EQ(p.next(), 10U);
  EXPECT_EQ(calls, (std::vector<std::size_t>{0}));
  EXPECT_EQ(p.next(), 11U);
  EXPECT_EQ(p.next(), 12U);
  EXPECT_TRUE(p.done());
  EXPECT_EQ(calls, (std::vector<std::size_t>{0, 1, 2}));
}

TEST(Prefetcher, NoItemsReadsNothing) {
  std::atomic<int> calls{0};
  Prefetcher<int> p(0, [&](std::size_t) { return ++calls; });
  EXPECT_TRUE(p.done());
  EXPECT_THROW((void)p.next(), std::out_of_range);
  EXPECT_EQ(calls.load(), 0);
}

TEST(Prefetcher, ReadsAtMostOneAheadAndNeverTwoAtOnce) {
  std::atomic<int> running{0};
  std::atomic<int> most{0};
  std::atomic<std::size_t> highest{0};
  Prefetcher<std::size_t> p(6, [&](std::size_t k) {
    const int now = ++running;
    most = std::max(most.load(), now);
    highest = std::max(highest.load(), k);
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
    --running;
    return k;
  });
  for (std::size_t k = 0; k < 3; ++k) {
    EXPECT_EQ(p.next(), k);
    std::this_thread::sleep_for(std::chrono::milliseconds(10));  // the caller's work on item k
    EXPECT_LE(highest.load(), k + 1) << "item " << k;
  }
  EXPECT_EQ(most.load(), 1);
}

TEST(Prefetcher, AReadsErrorIsThrownForItsItemAndNotBefore) {
  Prefetcher<int> p(4, [](std::size_t k) -> int {
    if (k == 2) throw std::runtime_error("scan 2 is damaged");
    return static_cast<int>(k);
  });
  EXPECT_EQ(p.next(), 0);
  EXPECT_EQ(p.next(), 1);
  try {
    (void)p.next();
    FAIL() << "no exception for item 2";
  } catch (const std::runtime_error& e) {
    EXPECT_STREQ(e.what(), "scan 2 is damaged");
  }
}

TEST(Prefetcher, StoppingEarlyWaitsForTheReadStillRunning) {
  std::atomic<bool> finished{false};
  {
    Prefetcher<int> p(3, [&](std::size_t k) {
      if (k == 1) {
        std::this_thread::sleep_for(std::chrono::milliseconds(30));
        finished = true;
      }
      return static_cast<int>(k);
    });
    EXPECT_EQ(p.next(), 0);  // item 1 is being read
  }
  EXPECT_TRUE(finished.load());  // the destructor waited for it
}

}  // namespace
}  // namespace hmap
