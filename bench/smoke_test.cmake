# bench.smoke: runs every benchmark family of kugel_bench once, at its smallest size, so that
# none can rot between the full runs by hand. Usage:
#   cmake -DBENCH=path/to/kugel_bench -DOUT=dir -P smoke_test.cmake
# A family is a benchmark's name without its last argument (integrator_step/3,
# gravity_tree/theta10:5, gas_step/continuous, decode_spawn); its smallest size is the
# smallest number in that last argument (a /real_time suffix, for benchmarks that run on
# several threads, is not an argument). Fails when listing or running fails, when a
# family's instance did not run, or when one reports an error.
cmake_minimum_required(VERSION 3.25)

execute_process(COMMAND ${BENCH} --benchmark_list_tests=true
  OUTPUT_VARIABLE listing RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "kugel_bench --benchmark_list_tests failed: ${rc}")
endif()
string(REGEX REPLACE "\n$" "" listing "${listing}")
string(REPLACE "\n" ";" names "${listing}")

set(families "")
foreach(name IN LISTS names)
  if(name MATCHES "^(.*)/([A-Za-z0-9_]+:)?([0-9]+)(/real_time)?$")
    set(family "${CMAKE_MATCH_1}")
    set(size "${CMAKE_MATCH_3}")
  else()
    set(family "${name}")
    set(size 0)
  endif()
  string(MAKE_C_IDENTIFIER "${family}" key)
  if(NOT DEFINED smallest_${key} OR size LESS smallest_size_${key})
    set(smallest_${key} "${name}")
    set(smallest_size_${key} "${size}")
  endif()
  if(NOT family IN_LIST families)
    list(APPEND families "${family}")
  endif()
endforeach()
list(LENGTH families family_count)
if(family_count EQUAL 0)
  message(FATAL_ERROR "kugel_bench lists no benchmarks")
endif()

set(chosen "")
foreach(family IN LISTS families)
  string(MAKE_C_IDENTIFIER "${family}" key)
  list(APPEND chosen "${smallest_${key}}")
endforeach()
list(JOIN chosen "|" alternatives)

# --benchmark_min_time=0: one iteration each (Google Benchmark 1.7 takes seconds; it stops
# as soon as the time run reaches the minimum).
file(MAKE_DIRECTORY ${OUT})
execute_process(COMMAND ${BENCH} "--benchmark_filter=^(${alternatives})$" --benchmark_min_time=0
  --benchmark_format=json --benchmark_out=${OUT}/bench_smoke.json --benchmark_out_format=json
  OUTPUT_QUIET RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "kugel_bench failed on the smallest sizes: ${rc}")
endif()

file(READ ${OUT}/bench_smoke.json report)
string(JSON run_count LENGTH "${report}" benchmarks)
set(ran "")
if(run_count GREATER 0)
  math(EXPR last "${run_count} - 1")
  foreach(i RANGE ${last})
    string(JSON name GET "${report}" benchmarks ${i} name)
    string(JSON failed ERROR_VARIABLE no_error GET "${report}" benchmarks ${i} error_occurred)
    if(failed)
      string(JSON why ERROR_VARIABLE no_message GET "${report}" benchmarks ${i} error_message)
      message(FATAL_ERROR "${name} reported an error: ${why}")
    endif()
    list(APPEND ran "${name}")
  endforeach()
endif()
foreach(name IN LISTS chosen)
  if(NOT name IN_LIST ran)
    message(FATAL_ERROR "family of ${name} did not run")
  endif()
endforeach()
message(STATUS "bench.smoke: ${family_count} families, each once at its smallest size: ${chosen}")
