// Refuses to start on a CPU below the instruction-set level the build targets
// (TRAINER_TARGET_ARCH, a CMake option, docs/performance.md "Build flags"). The rest of the
// program is compiled with -march=<level> and would die of SIGILL, without a word, at the first
// AVX2 or FMA instruction; this file is compiled for generic x86-64 and runs as a constructor
// ahead of every other static initialiser of the executable.
#include <cstdio>
#include <cstdlib>

#ifdef TRAINER_TARGET_ARCH
namespace {

__attribute__((constructor(101))) void trainer_refuse_cpu_below_target_level() {
  __builtin_cpu_init();
  if (__builtin_cpu_supports(TRAINER_TARGET_ARCH)) return;
  std::fputs("trainer: this CPU lacks the instruction-set level the program was built for ("
             TRAINER_TARGET_ARCH ", CMake option TRAINER_TARGET_ARCH); run it on a CPU with "
             TRAINER_TARGET_ARCH " or rebuild with -DTRAINER_TARGET_ARCH=x86-64 "
             "(docs/performance.md, Build flags)\n",
             stderr);
  std::_Exit(70);  // EX_SOFTWARE
}

}  // namespace
#endif
