// Hand-offs into and out of the 1 kHz servo cycle that never block it and never allocate
// once constructed: LossyRing, a fixed-capacity queue (producers serialize among themselves,
// e.g. with a mutex on their side only; the one consumer never waits), and LatestSlot, the
// newest value of a single writer (seqlock: the writer never waits, readers retry).
//
// Values are trivially copyable types held as arrays of atomic words, so a reader racing a
// writer reads torn words, never undefined behaviour, and the sequence checks discard them.
// A full ring overwrites its oldest entry; the consumer skips (and counts) what it lost.
// Clear drops everything queued so far (an operator's stop overtakes what came before it).
// Nothing here throws; misuse (two consumers, concurrent producers) is the caller's bug.
#pragma once

#include <algorithm>
#include <array>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <thread>
#include <type_traits>

namespace echoservo::live {

namespace lock_free_detail {

// A trivially copyable T stored as relaxed atomic 64-bit words.
template <class T>
class AtomicWords {
 public:
  static_assert(std::is_trivially_copyable_v<T>, "lock-free slots hold trivially copyable types");
  static constexpr std::size_t kWords = (sizeof(T) + 7) / 8;

  void Store(const T& value) {
    std::array<std::uint64_t, kWords> w{};
    std::memcpy(w.data(), &value, sizeof(T));
    for (std::size_t i = 0; i < kWords; ++i) words_[i].store(w[i], std::memory_order_relaxed);
  }
  void Load(T& out) const {
    std::array<std::uint64_t, kWords> w;
    for (std::size_t i = 0; i < kWords; ++i) w[i] = words_[i].load(std::memory_order_relaxed);
    // To void*: T is trivially copyable in its bytes (checked above) even when it has
    // default member initialisers, which GCC's -Wclass-memaccess reads as non-trivial.
    std::memcpy(static_cast<void*>(&out), w.data(), sizeof(T));
  }

 private:
  std::array<std::atomic<std::uint64_t>, kWords> words_{};
};

}  // namespace lock_free_detail

// Capacity N ≥ 1 entries. Push and Clear: one producer at a time (serialized by the caller).
// Drain: one consumer thread. Both are wait-free (bounded by N).
template <class T, std::size_t N>
class LossyRing {
 public:
  static_assert(N >= 1, "a ring holds at least one entry");
  static constexpr std::size_t kCapacity = N;

  // Appends `value`; when N entries are queued, the oldest is overwritten (the consumer
  // counts it as lost).
  void Push(const T& value) {
    const std::uint64_t i = tail_.load(std::memory_order_relaxed);
    Slot& s = slots_[i % N];
    s.version.store(2 * i + 1, std::memory_order_relaxed);  // writing entry i
    std::atomic_thread_fence(std::memory_order_release);
    s.value.Store(value);
    s.version.store(2 * i + 2, std::memory_order_release);  // entry i complete
    tail_.store(i + 1, std::memory_order_release);
    pushed_.fetch_add(1, std::memory_order_relaxed);
  }

  // Drops everything pushed so far (not counted as lost): the consumer starts after it.
  void Clear() { floor_.store(tail_.load(std::memory_order_relaxed), std::memory_order_release); }

  // Calls f(const T&) for each entry pushed since the last Drain and not cleared, oldest
  // first; returns how many. Entries overwritten before or while they were read are
  // skipped and counted in lost().
  template <class F>
  std::size_t Drain(F&& f) {
    // Tail first: a Clear before the newest push is then seen (release/acquire on tail).
    const std::uint64_t tail = tail_.load(std::memory_order_acquire);
    std::uint64_t i = std::min(tail, std::max(head_, floor_.load(std::memory_order_acquire)));
    if (tail - i > N) {  // overwritten before this Drain
      lost_ += tail - N - i;
      i = tail - N;
    }
    std::size_t n = 0;
    T value;
    for (; i < tail; ++i) {
      const Slot& s = slots_[i % N];
      const std::uint64_t v1 = s.version.load(std::memory_order_acquire);
      if (v1 == 2 * i + 2) {
        s.value.Load(value);
        std::atomic_thread_fence(std::memory_order_acquire);
        if (s.version.load(std::memory_order_relaxed) == v1) {
          f(static_cast<const T&>(value));
          ++n;
          continue;
        }
      }
      ++lost_;  // the producer has moved on past this entry
    }
    head_ = tail;
    return n;
  }

  // Producer-side count of pushes (any thread may read it).
  std::uint64_t pushed() const { return pushed_.load(std::memory_order_relaxed); }
  // Entries overwritten before the consumer read them (consumer thread).
  std::uint64_t lost() const { return lost_; }

 private:
  struct Slot {
    std::atomic<std::uint64_t> version{0};  // 2i+1 while entry i is written, 2i+2 after
    lock_free_detail::AtomicWords<T> value;
  };
  std::array<Slot, N> slots_{};
  alignas(64) std::atomic<std::uint64_t> tail_{0};  // next entry's index (producer)
  std::atomic<std::uint64_t> floor_{0};             // entries below it are cleared (producer)
  std::atomic<std::uint64_t> pushed_{0};
  alignas(64) std::uint64_t head_ = 0;  // next entry to read (consumer)
  std::uint64_t lost_ = 0;              // consumer
};

// The newest value of one writer thread. Write is wait-free; Read (any number of reader
// threads) retries while a write is in progress and returns the version it read.
template <class T>
class LatestSlot {
 public:
  // Stores `value` as the newest; returns its version (1, 2, …).
  std::uint64_t Write(const T& value) {
    const std::uint64_t s = seq_.load(std::memory_order_relaxed);
    seq_.store(s + 1, std::memory_order_relaxed);  // odd: writing
    std::atomic_thread_fence(std::memory_order_release);
    value_.Store(value);
    seq_.store(s + 2, std::memory_order_release);
    return (s + 2) / 2;
  }

  // The newest value into `out` and its version; 0 (and `out` untouched) before any Write.
  std::uint64_t Read(T& out) const {
    while (true) {
      const std::uint64_t s1 = seq_.load(std::memory_order_acquire);
      if (s1 == 0) return 0;
      if (s1 % 2 == 0) {
        T value;
        value_.Load(value);
        std::atomic_thread_fence(std::memory_order_acquire);
        if (seq_.load(std::memory_order_relaxed) == s1) {
          out = value;
          return s1 / 2;
        }
      }
      std::this_thread::yield();  // the writer is between its two stores
    }
  }

  // Version of the newest complete value (0 before any Write).
  std::uint64_t version() const { return seq_.load(std::memory_order_acquire) / 2; }

 private:
  std::atomic<std::uint64_t> seq_{0};
  lock_free_detail::AtomicWords<T> value_;
};

}  // namespace echoservo::live
