// Replacement global allocation functions that count allocations made by threads that opted
// in (core::alloc::begin_counting_this_thread). Linked as an OBJECT library into executables
// that must prove "no heap after arming" (the trainer, the tests). Counting is one TLS read
// and, when counting, one relaxed atomic add: cheap enough to stay in production builds.
//
// Under ASan/TSan the sanitizer runtime owns malloc, so only the operator new family is
// replaced there (still counted); in normal builds malloc/calloc/realloc and the aligned
// allocation functions are replaced too, forwarding to glibc's __libc_* entry points.
#include <cerrno>
#include <cstddef>
#include <cstdlib>
#include <new>

#include "trainer/core/alloc_counter.hpp"

#if !defined(TRAINER_SANITIZER_BUILD)
// glibc's own allocator entry points, which the replacements below forward to.
extern "C" {
void* __libc_malloc(std::size_t);                 // NOLINT
void* __libc_calloc(std::size_t, std::size_t);    // NOLINT
void* __libc_realloc(void*, std::size_t);         // NOLINT
void* __libc_memalign(std::size_t, std::size_t);  // NOLINT
void* __libc_valloc(std::size_t);                 // NOLINT
void* __libc_pvalloc(std::size_t);                // NOLINT
}
#endif

namespace {

namespace alloc = trainer::core::alloc;

#if defined(TRAINER_SANITIZER_BUILD)
constexpr bool kMallocFamilyReplaced = false;
#else
constexpr bool kMallocFamilyReplaced = true;
#endif

inline void count() noexcept {
  if (alloc::detail::this_thread_counting()) alloc::detail::count_one();
}

struct MarkInstalled {
  MarkInstalled() noexcept { alloc::detail::mark_hooks_installed(kMallocFamilyReplaced); }
};
const MarkInstalled g_mark_installed;

void* allocate(std::size_t size) noexcept {
  count();
#if defined(TRAINER_SANITIZER_BUILD)
  return std::malloc(size == 0 ? 1 : size);
#else
  return __libc_malloc(size == 0 ? 1 : size);
#endif
}

void* allocate_aligned(std::size_t size, std::size_t alignment) noexcept {
  count();
  if (alignment < sizeof(void*)) alignment = sizeof(void*);
#if defined(TRAINER_SANITIZER_BUILD)
  void* p = nullptr;
  return posix_memalign(&p, alignment, size == 0 ? 1 : size) == 0 ? p : nullptr;
#else
  return __libc_memalign(alignment, size == 0 ? 1 : size);
#endif
}

void* allocate_or_throw(std::size_t size) {
  for (;;) {
    if (void* p = allocate(size)) return p;
    std::new_handler handler = std::get_new_handler();
    if (handler == nullptr) throw std::bad_alloc();
    handler();
  }
}

void* allocate_aligned_or_throw(std::size_t size, std::size_t alignment) {
  for (;;) {
    if (void* p = allocate_aligned(size, alignment)) return p;
    std::new_handler handler = std::get_new_handler();
    if (handler == nullptr) throw std::bad_alloc();
    handler();
  }
}

}  // namespace

// ---- operator new / delete (every build) ----
void* operator new(std::size_t size) { return allocate_or_throw(size); }
void* operator new[](std::size_t size) { return allocate_or_throw(size); }
void* operator new(std::size_t size, const std::nothrow_t&) noexcept { return allocate(size); }
void* operator new[](std::size_t size, const std::nothrow_t&) noexcept { return allocate(size); }
void* operator new(std::size_t size, std::align_val_t al) {
  return allocate_aligned_or_throw(size, static_cast<std::size_t>(al));
}
void* operator new[](std::size_t size, std::align_val_t al) {
  return allocate_aligned_or_throw(size, static_cast<std::size_t>(al));
}
void* operator new(std::size_t size, std::align_val_t al, const std::nothrow_t&) noexcept {
  return allocate_aligned(size, static_cast<std::size_t>(al));
}
void* operator new[](std::size_t size, std::align_val_t al, const std::nothrow_t&) noexcept {
  return allocate_aligned(size, static_cast<std::size_t>(al));
}

void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }
void operator delete(void* p, const std::nothrow_t&) noexcept { std::free(p); }
void operator delete[](void* p, const std::nothrow_t&) noexcept { std::free(p); }
void operator delete(void* p, std::align_val_t) noexcept { std::free(p); }
void operator delete[](void* p, std::align_val_t) noexcept { std::free(p); }
void operator delete(void* p, std::size_t, std::align_val_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t, std::align_val_t) noexcept { std::free(p); }
void operator delete(void* p, std::align_val_t, const std::nothrow_t&) noexcept { std::free(p); }
void operator delete[](void* p, std::align_val_t, const std::nothrow_t&) noexcept { std::free(p); }

// ---- malloc family (non-sanitizer builds) ----
#if !defined(TRAINER_SANITIZER_BUILD)
extern "C" {
void* malloc(std::size_t size) {
  count();
  return __libc_malloc(size);
}
void* calloc(std::size_t n, std::size_t size) {
  count();
  return __libc_calloc(n, size);
}
void* realloc(void* p, std::size_t size) {
  count();
  return __libc_realloc(p, size);
}
void* memalign(std::size_t alignment, std::size_t size) {
  count();
  return __libc_memalign(alignment, size);
}
void* aligned_alloc(std::size_t alignment, std::size_t size) {
  count();
  return __libc_memalign(alignment, size);
}
int posix_memalign(void** out, std::size_t alignment, std::size_t size) {
  if (alignment < sizeof(void*) || (alignment & (alignment - 1)) != 0) return EINVAL;
  count();
  void* p = __libc_memalign(alignment, size);
  if (p == nullptr) return ENOMEM;
  *out = p;
  return 0;
}
void* valloc(std::size_t size) {
  count();
  return __libc_valloc(size);
}
void* pvalloc(std::size_t size) {
  count();
  return __libc_pvalloc(size);
}
}  // extern "C"
#endif
