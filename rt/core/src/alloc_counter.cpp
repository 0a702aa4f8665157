#include "trainer/core/alloc_counter.hpp"

#include <atomic>

namespace trainer::core::alloc {

namespace {
std::atomic<bool> g_hooks_installed{false};
std::atomic<bool> g_malloc_family{false};
std::atomic<std::uint64_t> g_counted{0};
// initial-exec TLS: reading it never allocates, so it is safe inside malloc itself.
thread_local bool t_counting __attribute__((tls_model("initial-exec"))) = false;
}  // namespace

bool hooks_installed() noexcept { return g_hooks_installed.load(std::memory_order_relaxed); }
bool malloc_family_counted() noexcept { return g_malloc_family.load(std::memory_order_relaxed); }
void begin_counting_this_thread() noexcept { t_counting = true; }
void end_counting_this_thread() noexcept { t_counting = false; }
std::uint64_t counted_allocations() noexcept { return g_counted.load(std::memory_order_relaxed); }

namespace detail {
void mark_hooks_installed(bool malloc_family) noexcept {
  g_hooks_installed.store(true, std::memory_order_relaxed);
  g_malloc_family.store(malloc_family, std::memory_order_relaxed);
}
bool this_thread_counting() noexcept { return t_counting; }
void count_one() noexcept { g_counted.fetch_add(1, std::memory_order_relaxed); }
}  // namespace detail

}  // namespace trainer::core::alloc
