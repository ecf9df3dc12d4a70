# Warnings and sanitizers for every Kugel target, through one interface target.
add_library(kugel_options INTERFACE)
target_compile_options(kugel_options INTERFACE
  -Wall -Wextra -Wpedantic -Wconversion -Wshadow -Wnon-virtual-dtor -Wold-style-cast
  # Settings structs give every field a default and are filled with designated initializers
  # ({.integrator = rk4}); GCC 12 would still flag each field left to its default.
  -Wno-missing-field-initializers
  # No fused multiply-add unless the source writes one: a*b+c is rounded twice, as the
  # golden state hashes assume, on every machine and with every compiler (GCC fuses across
  # statements by default where the target has FMA). tests/layers pins it.
  -ffp-contract=off)
if(KUGEL_WERROR)
  target_compile_options(kugel_options INTERFACE -Werror)
endif()
if(KUGEL_NO_SSE2)
  # The dev preset builds the scalar versions of the engine's few SSE2 comparisons, so that
  # its tests (the golden hashes among them) hold them to the same results as release's.
  target_compile_definitions(kugel_options INTERFACE KUGEL_NO_SSE2)
endif()
if(KUGEL_SANITIZE OR KUGEL_FUZZ)
  target_compile_options(kugel_options INTERFACE
    -fsanitize=address,undefined -fno-sanitize-recover=all -fno-omit-frame-pointer)
  target_link_options(kugel_options INTERFACE -fsanitize=address,undefined)
endif()
if(KUGEL_TSAN)
  # -Wno-tsan, for GCC (the preset uses clang): GCC warns that TSan does not model
  # atomic_thread_fence, which Asio's scheduler uses; the fence sits next to the mutexes TSan
  # does see.
  target_compile_options(kugel_options INTERFACE -fsanitize=thread -fno-omit-frame-pointer
    $<$<CXX_COMPILER_ID:GNU>:-Wno-tsan>)
  target_link_options(kugel_options INTERFACE -fsanitize=thread)
endif()

# The sanitized presets build Debug at -O1 (the engine's Eigen loops at -O0 would run the
# physics tests ten times slower). The files named here instantiate Beast's WebSocket and
# HTTP stream templates and run no physics: they compile at -O0, in a third to a half of the
# time. Only such files: an inline function compiled into an -O0 and an -O1 object is kept
# once at link, from whichever comes first, and an engine whose vectors resolved to -O0
# copies ran its tests at -O0 speed.
function(kugel_compile_quickly_in_debug)
  set_source_files_properties(${ARGN} PROPERTIES COMPILE_OPTIONS $<$<CONFIG:Debug>:-O0>)
endfunction()
