#pragma once
// The parallel loops of the model and the packing: tbb::parallel_for, or, under
// ThreadSanitizer, plain threads. (The voxels, level sets, FFT and writers call TBB directly:
// the ThreadSanitizer run covers the packing.)
//
// Debian's libtbb is not built with ThreadSanitizer, so the waits that end a parallel_for run in
// code it cannot see, and it reports TBB's own bookkeeping and the calling thread's next use of
// memory a worker touched as races. Under ThreadSanitizer (the RVEGEN_TSAN build, .ci/tsan.sh)
// these loops run their pieces of work on std::threads that take them in turn and are joined,
// which it sees whole: what it reports then is a race of rvegen's own loop bodies. The pieces
// are the same (ranges split at their grain), and the loops' results do not depend on which
// thread runs which piece, so the RVE is the same.
#include <tbb/parallel_for.h>
#include <tbb/parallel_sort.h>

#include <algorithm>
#include <functional>

#if defined(__has_feature)
#if __has_feature(thread_sanitizer)
#define RVEGEN_TSAN 1
#endif
#endif
#if defined(__SANITIZE_THREAD__) && !defined(RVEGEN_TSAN)
#define RVEGEN_TSAN 1
#endif
#ifdef RVEGEN_TSAN
#include <tbb/task_arena.h>

#include <atomic>
#include <thread>
#include <vector>
#endif

namespace rvegen {

#ifdef RVEGEN_TSAN
namespace detail {
/// work(k) for k in [0, count) on as many std::threads as the arena allows, joined.
template <typename Work>
void run_on_threads(size_t count, const Work& work) {
  const size_t n = std::min<size_t>(count, std::max(1, tbb::this_task_arena::max_concurrency()));
  std::atomic<size_t> next{0};
  const auto take = [&] {
    for (size_t k = next++; k < count; k = next++) work(k);
  };
  std::vector<std::thread> threads;
  for (size_t t = 1; t < n; ++t) threads.emplace_back(take);
  take();
  for (std::thread& t : threads) t.join();
}
}  // namespace detail
#endif

/// tbb::parallel_for(first, last, f): f(i) for every i in [first, last).
template <typename Index, typename Fn>
void parallel_for(Index first, Index last, const Fn& f) {
#ifdef RVEGEN_TSAN
  if (last > first) {
    detail::run_on_threads(static_cast<size_t>(last - first),
                           [&](size_t k) { f(static_cast<Index>(first + k)); });
  }
#else
  tbb::parallel_for(first, last, f);
#endif
}

/// tbb::parallel_for(range, f, partitioner...): f(sub-range) over pieces of a blocked_range.
template <typename Range, typename Fn, typename... Partitioner>
void parallel_for_range(const Range& range, const Fn& f, const Partitioner&... partitioner) {
#ifdef RVEGEN_TSAN
  (void)sizeof...(partitioner);
  const size_t grain = std::max<size_t>(1, range.grainsize());
  const size_t size = range.end() - range.begin();
  detail::run_on_threads((size + grain - 1) / grain, [&](size_t k) {
    const auto lo = range.begin() + k * grain;
    const auto hi = std::min(range.end(), lo + grain);
    f(Range(lo, hi, grain));
  });
#else
  tbb::parallel_for(range, f, partitioner...);
#endif
}

/// tbb::parallel_sort(first, last, less); under ThreadSanitizer std::sort (its pieces of work
/// cannot be told the fork). The same order either way for keys whose equal ones are equal
/// (`less` a strict order: elements it does not tell apart come out in any order); without
/// `less`, std::less.
template <typename It, typename Less>
void parallel_sort(It first, It last, const Less& less) {
#ifdef RVEGEN_TSAN
  std::sort(first, last, less);
#else
  tbb::parallel_sort(first, last, less);
#endif
}
template <typename It>
void parallel_sort(It first, It last) {
  parallel_sort(first, last, std::less<>());
}

}  // namespace rvegen
