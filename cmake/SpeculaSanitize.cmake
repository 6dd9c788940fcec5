# -DSPECULA_SANITIZE=ON: AddressSanitizer and UndefinedBehaviorSanitizer on every target
# (compile and link), frame pointers kept for the reports, and no recovery: the first report
# ends the process with a non-zero status, so a test that triggers one fails. Use a build
# folder of its own (the flags change every object):
#   cmake -S . -B build-asan -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DSPECULA_SANITIZE=ON
#   cmake --build build-asan && ctest --test-dir build-asan
# Every executable gets cmake/sanitize/defaults.cpp, which hands the runtimes their default
# options (halt on the first report, the leak suppressions in cmake/sanitize/lsan.supp), so
# plain ctest runs them right (ASAN_OPTIONS / UBSAN_OPTIONS / LSAN_OPTIONS still override),
# and keeps modules loaded: its dlclose does nothing, so LeakSanitizer still sees the blocks
# an unloaded Vulkan driver holds in its globals.
option(SPECULA_SANITIZE "Build with AddressSanitizer + UndefinedBehaviorSanitizer (use a separate build folder)" OFF)

if(SPECULA_SANITIZE)
  set(SPECULA_SANITIZE_FLAGS -fsanitize=address,undefined -fno-omit-frame-pointer -fno-sanitize-recover=all)
  add_compile_options(${SPECULA_SANITIZE_FLAGS})
  add_link_options(${SPECULA_SANITIZE_FLAGS})
endif()

# Called once every target exists (the end of the top-level CMakeLists.txt): adds the runtime
# defaults to every executable below `dir`.
function(specula_sanitize_executables dir)
  if(NOT SPECULA_SANITIZE)
    return()
  endif()
  get_property(targets DIRECTORY ${dir} PROPERTY BUILDSYSTEM_TARGETS)
  foreach(t IN LISTS targets)
    get_target_property(type ${t} TYPE)
    if(type STREQUAL "EXECUTABLE")
      target_sources(${t} PRIVATE ${PROJECT_SOURCE_DIR}/cmake/sanitize/defaults.cpp)
      target_compile_definitions(${t} PRIVATE SPECULA_LSAN_SUPPRESSIONS="${PROJECT_SOURCE_DIR}/cmake/sanitize/lsan.supp")
      # defaults.cpp's dlclose replaces libc's for every library (see there why).
      target_link_options(${t} PRIVATE -Wl,--export-dynamic-symbol=dlclose)
    endif()
  endforeach()
  get_property(subdirs DIRECTORY ${dir} PROPERTY SUBDIRECTORIES)
  foreach(sub IN LISTS subdirs)
    specula_sanitize_executables(${sub})
  endforeach()
endfunction()
