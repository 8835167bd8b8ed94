# SPDX-License-Identifier: GPL-3.0-or-later
include(CMakePackageConfigHelpers)
install(TARGETS rpiv EXPORT rpivTargets
  LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR}
  ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
  RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
install(TARGETS rpiv_static ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR})
install(TARGETS rpiv_cli RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
install(FILES ${RPIV_HEADERS} ${CMAKE_CURRENT_BINARY_DIR}/include/rpiv/version.h
  DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/rpiv)
install(FILES docs/rpiv.1 DESTINATION ${CMAKE_INSTALL_MANDIR}/man1)

install(EXPORT rpivTargets NAMESPACE rpiv:: DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/rpiv)
configure_package_config_file(cmake/rpivConfig.cmake.in
  ${CMAKE_CURRENT_BINARY_DIR}/rpivConfig.cmake
  INSTALL_DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/rpiv)
write_basic_package_version_file(${CMAKE_CURRENT_BINARY_DIR}/rpivConfigVersion.cmake
  COMPATIBILITY SameMajorVersion)
install(FILES ${CMAKE_CURRENT_BINARY_DIR}/rpivConfig.cmake
  ${CMAKE_CURRENT_BINARY_DIR}/rpivConfigVersion.cmake
  DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/rpiv)

configure_file(cmake/rpiv.pc.in ${CMAKE_CURRENT_BINARY_DIR}/rpiv.pc @ONLY)
install(FILES ${CMAKE_CURRENT_BINARY_DIR}/rpiv.pc DESTINATION ${CMAKE_INSTALL_LIBDIR}/pkgconfig)
