# Installation: `cmake --install build --prefix P` puts
#   bin/haarlight                          the command (the viewer is `haarlight view`)
#   lib/libhaarlight.so.0 (SONAME)         the shared library, public API only
#   include/haarlight.h                    its header
#   lib/cmake/haarlight/                   find_package(haarlight) -> haarlight::haarlight
#   lib/pkgconfig/haarlight.pc             pkg-config haarlight
#   share/man/man1/haarlight.1             generated from the commands' --help (help2man)
# The kernels are embedded in the library, so nothing else is needed at
# run time. Included from the top level after every target exists.
include(GNUInstallDirs)
include(CMakePackageConfigHelpers)

add_library(haarlight_shared SHARED)
target_link_libraries(haarlight_shared PRIVATE haarlight_objs)
target_include_directories(haarlight_shared INTERFACE $<BUILD_INTERFACE:${CMAKE_SOURCE_DIR}/host/include>
                                                      $<INSTALL_INTERFACE:${CMAKE_INSTALL_INCLUDEDIR}>)
set_target_properties(haarlight_shared PROPERTIES OUTPUT_NAME haarlight EXPORT_NAME haarlight
                      VERSION ${PROJECT_VERSION} SOVERSION ${PROJECT_VERSION_MAJOR})
add_library(haarlight::haarlight ALIAS haarlight_shared)

install(TARGETS haarlight RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
install(TARGETS haarlight_shared EXPORT haarlightTargets
        LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR}
        INCLUDES DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
install(FILES ${CMAKE_SOURCE_DIR}/host/include/haarlight.h DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
set(HL_CMAKE_DIR ${CMAKE_INSTALL_LIBDIR}/cmake/haarlight)
install(EXPORT haarlightTargets NAMESPACE haarlight:: DESTINATION ${HL_CMAKE_DIR})
file(WRITE ${CMAKE_BINARY_DIR}/haarlightConfig.cmake
     "include(\"\${CMAKE_CURRENT_LIST_DIR}/haarlightTargets.cmake\")\n")
write_basic_package_version_file(${CMAKE_BINARY_DIR}/haarlightConfigVersion.cmake
                                 VERSION ${PROJECT_VERSION} COMPATIBILITY SameMajorVersion)
install(FILES ${CMAKE_BINARY_DIR}/haarlightConfig.cmake ${CMAKE_BINARY_DIR}/haarlightConfigVersion.cmake
        DESTINATION ${HL_CMAKE_DIR})

# pkg-config: the prefix is found from the .pc file's own place, so the
# same file serves any --prefix given at install time
file(RELATIVE_PATH HL_PC_TO_PREFIX /${CMAKE_INSTALL_LIBDIR}/pkgconfig /)
configure_file(${CMAKE_SOURCE_DIR}/host/haarlight.pc.in ${CMAKE_BINARY_DIR}/haarlight.pc @ONLY)
install(FILES ${CMAKE_BINARY_DIR}/haarlight.pc DESTINATION ${CMAKE_INSTALL_LIBDIR}/pkgconfig)

# The manual: help2man runs `haarlight --help` and `--version`, and
# host/man.cmake adds each command's --help as a section of its own.
find_program(HL_HELP2MAN help2man)
if(HL_HELP2MAN)
  add_custom_command(OUTPUT ${CMAKE_BINARY_DIR}/haarlight.1
    COMMAND ${CMAKE_COMMAND} -DBIN=$<TARGET_FILE:haarlight> -DHELP2MAN=${HL_HELP2MAN}
            -DOUT=${CMAKE_BINARY_DIR}/haarlight.1 -P ${CMAKE_SOURCE_DIR}/host/man.cmake
    DEPENDS haarlight ${CMAKE_SOURCE_DIR}/host/man.cmake
    COMMENT "Writing the manual page (help2man)" VERBATIM)
  add_custom_target(haarlight_man ALL DEPENDS ${CMAKE_BINARY_DIR}/haarlight.1)
  install(FILES ${CMAKE_BINARY_DIR}/haarlight.1 DESTINATION ${CMAKE_INSTALL_MANDIR}/man1)
else()
  message(STATUS "help2man not found: the manual page is not built or installed (Debian: help2man)")
endif()
