// Default options of the sanitizer runtimes, compiled into every executable of a
// -DSPECULA_SANITIZE=ON build (cmake/SpeculaSanitize.cmake). The runtimes call these hooks
// before main() (they read their options before any constructor could set the environment);
// ASAN_OPTIONS, UBSAN_OPTIONS and LSAN_OPTIONS in the environment still override them.
extern "C" {

// Halt at the first error (with -fno-sanitize-recover=all the process ends with status 1);
// leaks are reported at exit. detect_stack_use_after_return catches pointers into dead frames.
const char* __asan_default_options() { return "halt_on_error=1:detect_leaks=1:detect_stack_use_after_return=1"; }

const char* __ubsan_default_options() { return "halt_on_error=1:print_stacktrace=1"; }

// Leaks inside system libraries, not Specula's (see the file for each entry). The count of
// suppressed blocks is not printed: with log_path set (tools/run-sanitized-tests.sh) it would
// land in a report file, and any file there fails the run.
const char* __lsan_default_options() { return "suppressions=" SPECULA_LSAN_SUPPRESSIONS ":print_suppressions=0"; }

// Modules stay loaded. LeakSanitizer counts a heap block as reachable when a pointer to it
// lies in a loaded module's data. The Vulkan loader unloads the driver at vkDestroyInstance,
// and Mesa's lavapipe (libvulkan_lvp.so) keeps blocks in its globals that it never frees: once
// the driver is unloaded they were reported as leaks at exit (240 bytes in 3 blocks for a
// small reconstruct, 130 KB in 643 for a large one, every stack ending in the unloaded
// module), failing every test that creates a Vulkan device. With the driver kept loaded the
// blocks are reachable and nothing is reported; the process frees them when it ends. This
// definition is exported from the executable (SpeculaSanitize.cmake), so it takes the place
// of libc's dlclose for every library.
int dlclose(void*) { return 0; }

} // extern "C"
