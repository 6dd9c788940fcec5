// Default options of the sanitizer runtimes, compiled into every executable of a
// -DSPECULA_SANITIZE=ON build (cmake/SpeculaSanitize.cmake). The runtimes call these hooks
// before main() (they read their options before any constructor could set the environment);
// ASAN_OPTIONS, UBSAN_OPTIONS and LSAN_OPTIONS in the environment still override them.
extern "C" {

// Halt at the first error (with -fno-sanitize-recover=all the process ends with status 1);
// leaks are reported at exit. detect_stack_use_after_return catches pointers into dead frames.
const char* __asan_default_options() { return "halt_on_error=1:detect_leaks=1:detect_stack_use_after_return=1"; }

const char* __ubsan_default_options() { return "halt_on_error=1:print_stacktrace=1"; }

// Leaks inside the system's Vulkan stack, not Specula's (see the file for each entry).
const char* __lsan_default_options() { return "suppressions=" SPECULA_LSAN_SUPPRESSIONS; }

} // extern "C"
