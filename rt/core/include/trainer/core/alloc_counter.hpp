// Counts heap allocations made by threads that opted in (the RT thread, after arming).
// The counting itself lives in the `trainer::alloc_hooks` object library, which replaces the
// global operator new family and malloc/calloc/realloc/aligned allocation functions; link it
// into an executable to enable counting. Without it, hooks_installed() is false and reports
// must say the count was not measured.
#pragma once

#include <cstdint>

namespace trainer::core::alloc {

// True when the replacement allocation functions are linked into this program.
bool hooks_installed() noexcept;
// While enabled on a thread, every allocation that thread makes is counted.
void begin_counting_this_thread() noexcept;
void end_counting_this_thread() noexcept;
// Allocations counted across all counting threads since program start.
std::uint64_t counted_allocations() noexcept;
// Whether malloc-family calls are counted too (false in sanitizer builds, where the
// sanitizer owns malloc; operator new is counted in every build).
bool malloc_family_counted() noexcept;

namespace detail {
// Used by the hooks; not for other callers.
void mark_hooks_installed(bool malloc_family) noexcept;
bool this_thread_counting() noexcept;
void count_one() noexcept;
}  // namespace detail

}  // namespace trainer::core::alloc
