# `cmake --install BUILD --prefix PREFIX` installs kugel-server with its scenes and page, and
# the client library for programs of one's own: kugel_client and kugel_protocol (static),
# their headers, kugel-client, and a CMake package, so that a project outside this tree writes
#   find_package(Kugel 0.1 REQUIRED)
#   target_link_libraries(app PRIVATE Kugel::client)
# tests/install builds such a project against an installed tree.
include(CMakePackageConfigHelpers)

install(TARGETS kugel_protocol kugel_client EXPORT KugelTargets
  ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR})
install(FILES protocol/codec.hpp protocol/compact.hpp protocol/error_code.hpp protocol/messages.hpp
  DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/protocol)
install(FILES client/connection.hpp client/latency_histogram.hpp client/stalled_connection.hpp
  client/url.hpp
  DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/client)
install(TARGETS kugel-client RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})

# The server as a packaged one runs: kugel-server in bin, its scenes and the built page in
# share/kugel, where a kugel-server run without --web-root finds the page
# (server/static_files.hpp, page_places).
install(TARGETS kugel-server RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
install(DIRECTORY scenes/ DESTINATION ${CMAKE_INSTALL_DATADIR}/kugel/scenes
  FILES_MATCHING PATTERN "*.json" PATTERN "README.md")
if(TARGET web)
  install(DIRECTORY web/dist/ DESTINATION ${CMAKE_INSTALL_DATADIR}/kugel/web)
endif()

set(kugel_package_dir ${CMAKE_INSTALL_LIBDIR}/cmake/Kugel)
install(EXPORT KugelTargets NAMESPACE Kugel:: FILE KugelTargets.cmake DESTINATION ${kugel_package_dir})
configure_package_config_file(cmake/KugelConfig.cmake.in ${PROJECT_BINARY_DIR}/KugelConfig.cmake
  INSTALL_DESTINATION ${kugel_package_dir})
write_basic_package_version_file(${PROJECT_BINARY_DIR}/KugelConfigVersion.cmake
  COMPATIBILITY SameMinorVersion)
install(FILES ${PROJECT_BINARY_DIR}/KugelConfig.cmake ${PROJECT_BINARY_DIR}/KugelConfigVersion.cmake
  DESTINATION ${kugel_package_dir})
