# The layer rule of docs/architecture.md, checked on the sources: each layer includes only
# the layers below it and the libraries it may use. Run as
#   cmake -DROOT=<source tree> [-DCOMPILE_COMMANDS=<compile_commands.json>] -P check_layers.cmake
# and it fails, naming every file and include at fault. With COMPILE_COMMANDS it also checks
# that every engine source is compiled with -ffp-contract=off (the golden hashes assume no
# fused multiply-add).
#
# An include is a layer's when it starts with the layer's folder ("physics/world.hpp"); a
# quoted include without a folder must name a file beside the including one; "../" is never
# allowed. An angle include names a library by its first path part (nlohmann, boost, ...);
# one without a folder (<vector>, <immintrin.h>) is the standard library or the compiler's.

cmake_minimum_required(VERSION 3.25)
if(NOT DEFINED ROOT)
  message(FATAL_ERROR "give -DROOT=<source tree>")
endif()

# layer: what it must not include (layers above it, libraries it must not use)
set(forbidden_physics  scene protocol server client nlohmann spdlog fmt boost CLI)
set(forbidden_scene    protocol server client spdlog fmt boost CLI)
set(forbidden_protocol physics scene server client spdlog fmt boost CLI Eigen)
set(forbidden_server   client)
set(forbidden_client   physics scene server Eigen)

set(faults "")
set(checked 0)
foreach(layer physics scene protocol server client)
  file(GLOB_RECURSE sources RELATIVE "${ROOT}" "${ROOT}/${layer}/*.hpp" "${ROOT}/${layer}/*.cpp")
  foreach(source ${sources})
    math(EXPR checked "${checked} + 1")
    get_filename_component(folder "${ROOT}/${source}" DIRECTORY)
    file(STRINGS "${ROOT}/${source}" includes REGEX "^[ \t]*#[ \t]*include[ \t]*[<\"]")
    foreach(line ${includes})
      string(REGEX MATCH "[<\"]([^>\"]+)[>\"]" _ "${line}")
      set(target "${CMAKE_MATCH_1}")
      string(REGEX MATCH "^[^/]+" first "${target}")
      if(target MATCHES "\\.\\./")
        list(APPEND faults "${source}: ${line} (no include climbs out of its folder)")
      elseif(first IN_LIST forbidden_${layer})
        list(APPEND faults "${source}: ${line} (${layer}/ may not include ${first})")
      elseif(line MATCHES "\"" AND NOT target MATCHES "/" AND NOT EXISTS "${folder}/${target}")
        list(APPEND faults "${source}: ${line} (no such file beside it)")
      endif()
    endforeach()
  endforeach()
endforeach()

if(DEFINED COMPILE_COMMANDS)
  file(READ "${COMPILE_COMMANDS}" commands)
  string(JSON count LENGTH "${commands}")
  math(EXPR last "${count} - 1")
  set(engine_sources 0)
  foreach(i RANGE ${last})
    string(JSON file GET "${commands}" ${i} file)
    if(file MATCHES "/physics/.+\\.cpp$" AND NOT file MATCHES "/tests/")
      math(EXPR engine_sources "${engine_sources} + 1")
      string(JSON command GET "${commands}" ${i} command)
      if(NOT command MATCHES "-ffp-contract=off")
        list(APPEND faults "${file}: compiled without -ffp-contract=off")
      endif()
    endif()
  endforeach()
  if(engine_sources EQUAL 0)
    list(APPEND faults "${COMPILE_COMMANDS}: no engine source in it")
  endif()
endif()

if(faults)
  list(JOIN faults "\n  " text)
  message(FATAL_ERROR "the layer rule is broken:\n  ${text}")
endif()
message(STATUS "layers: every include of ${checked} files points down a layer")
