# Installs the build tree into a fresh prefix and builds tests/install/outside against it,
# then runs that program. Run as
#   cmake -DBUILD=<build tree> -DSOURCE=<source tree> -DWORK=<scratch dir> -P check_install.cmake
foreach(var BUILD SOURCE WORK)
  if(NOT DEFINED ${var})
    message(FATAL_ERROR "give -D${var}=...")
  endif()
endforeach()
file(REMOVE_RECURSE "${WORK}")
set(prefix "${WORK}/prefix")
function(run)
  execute_process(COMMAND ${ARGN} RESULT_VARIABLE code OUTPUT_VARIABLE out ERROR_VARIABLE err)
  if(NOT code EQUAL 0)
    message(FATAL_ERROR "failed (${code}): ${ARGN}\n${out}\n${err}")
  endif()
  set(out "${out}" PARENT_SCOPE)
endfunction()
run(${CMAKE_COMMAND} --install "${BUILD}" --prefix "${prefix}")
foreach(file include/client/connection.hpp include/protocol/codec.hpp bin/kugel-client
             lib/cmake/Kugel/KugelConfig.cmake bin/kugel-server share/kugel/scenes/arena.json
             share/kugel/scenes/README.md)
  if(NOT EXISTS "${prefix}/${file}")
    message(FATAL_ERROR "not installed: ${file}")
  endif()
endforeach()
# The installed server finds the installed page by itself (when the page was built: it needs
# Node.js). Stopped by SIGTERM after a few seconds; what counts is the line it logged.
if(EXISTS "${SOURCE}/web/dist/index.html")
  if(NOT EXISTS "${prefix}/share/kugel/web/index.html")
    message(FATAL_ERROR "not installed: share/kugel/web/index.html")
  endif()
  execute_process(COMMAND timeout -s TERM 5 "${prefix}/bin/kugel-server" --port 0
    OUTPUT_VARIABLE server_out ERROR_VARIABLE server_log)
  string(FIND "${server_log}" "the page: ${prefix}/share/kugel/web (in the install prefix" at)
  if(at EQUAL -1)
    message(FATAL_ERROR "the installed kugel-server did not serve the installed page; its log:\n${server_log}")
  endif()
endif()
run(${CMAKE_COMMAND} -S "${SOURCE}/tests/install/outside" -B "${WORK}/outside" -G Ninja
    -DCMAKE_PREFIX_PATH=${prefix} -DCMAKE_BUILD_TYPE=Release)
run(${CMAKE_COMMAND} --build "${WORK}/outside")
run("${WORK}/outside/outside")
set(expected "ws://127.0.0.1:1/ws/lab\n{\"type\":\"ping\",\"ref\":7}\nno server\n")
if(NOT out STREQUAL expected)
  message(FATAL_ERROR "the outside program printed\n${out}\ninstead of\n${expected}")
endif()
message(STATUS "installed, found by find_package(Kugel), linked and run")
