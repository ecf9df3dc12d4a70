# Warnings and sanitizers for every Kugel target, through one interface target.
add_library(kugel_options INTERFACE)
target_compile_options(kugel_options INTERFACE
  -Wall -Wextra -Wpedantic -Wconversion -Wshadow -Wnon-virtual-dtor -Wold-style-cast
  # Settings structs give every field a default and are filled with designated initializers
  # ({.integrator = rk4}); GCC 12 would still flag each field left to its default.
  -Wno-missing-field-initializers)
if(KUGEL_WERROR)
  target_compile_options(kugel_options INTERFACE -Werror)
endif()
if(KUGEL_SANITIZE)
  target_compile_options(kugel_options INTERFACE
    -fsanitize=address,undefined -fno-sanitize-recover=all -fno-omit-frame-pointer)
  target_link_options(kugel_options INTERFACE -fsanitize=address,undefined)
endif()
if(KUGEL_TSAN)
  # -Wno-tsan: GCC warns that TSan does not model atomic_thread_fence, which Asio's
  # scheduler uses; the fence sits next to the mutexes TSan does see.
  target_compile_options(kugel_options INTERFACE -fsanitize=thread -fno-omit-frame-pointer -Wno-tsan)
  target_link_options(kugel_options INTERFACE -fsanitize=thread)
endif()
if(KUGEL_FUZZ)
  # Coverage for libFuzzer in every library; the fuzz executables add -fsanitize=fuzzer.
  target_compile_options(kugel_options INTERFACE
    -fsanitize=fuzzer-no-link,address,undefined -fno-sanitize-recover=all -fno-omit-frame-pointer)
  target_link_options(kugel_options INTERFACE -fsanitize=address,undefined)
endif()
