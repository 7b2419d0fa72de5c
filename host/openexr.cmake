# OpenEXR for host/src/io/exr_io.c and host/src/io/exr_check.c (the only files
# that include its headers).
#
# Defines the interface target hl_openexr: the C wrapper of the C++ library
# (ImfCRgbaFile.h), which decodes DWAB where Debian 12's OpenEXRCore cannot,
# and OpenEXRCore (openexr.h), which reads and writes 32-bit floats.
# Found through pkg-config (OpenEXR.pc) when available, else from the
# explicit Debian paths. When the haarlight_objs target already exists it is
# linked here, so the top level needs only include() after that target.
if(NOT TARGET hl_openexr)
  add_library(hl_openexr INTERFACE)
  find_package(PkgConfig QUIET)
  if(PkgConfig_FOUND)
    pkg_check_modules(HL_OPENEXR_PC QUIET IMPORTED_TARGET OpenEXR)
  endif()
  if(HL_OPENEXR_PC_FOUND)
    target_link_libraries(hl_openexr INTERFACE PkgConfig::HL_OPENEXR_PC)
  else()
    find_path(HL_OPENEXR_INCLUDE_DIR ImfCRgbaFile.h PATHS /usr/include/OpenEXR PATH_SUFFIXES OpenEXR)
    find_path(HL_IMATH_INCLUDE_DIR ImathConfig.h PATHS /usr/include/Imath PATH_SUFFIXES Imath)
    find_library(HL_OPENEXR_LIB NAMES OpenEXR-3_1 OpenEXR)
    find_library(HL_OPENEXR_CORE_LIB NAMES OpenEXRCore-3_1 OpenEXRCore)
    find_library(HL_IEX_LIB NAMES Iex-3_1 Iex)
    find_library(HL_IMATH_LIB NAMES Imath-3_1 Imath)
    if(NOT HL_OPENEXR_INCLUDE_DIR OR NOT HL_IMATH_INCLUDE_DIR OR NOT HL_OPENEXR_LIB
       OR NOT HL_OPENEXR_CORE_LIB OR NOT HL_IEX_LIB OR NOT HL_IMATH_LIB)
      message(FATAL_ERROR "OpenEXR not found: need ImfCRgbaFile.h, openexr.h, ImathConfig.h and "
                          "libOpenEXR-3_1, libOpenEXRCore-3_1, libIex-3_1, libImath-3_1 "
                          "(Debian: libopenexr-dev)")
    endif()
    target_include_directories(hl_openexr INTERFACE ${HL_OPENEXR_INCLUDE_DIR} ${HL_IMATH_INCLUDE_DIR})
    target_link_libraries(hl_openexr INTERFACE ${HL_OPENEXR_LIB} ${HL_OPENEXR_CORE_LIB} ${HL_IEX_LIB}
                          ${HL_IMATH_LIB})
  endif()
endif()
if(TARGET haarlight_objs)
  target_link_libraries(haarlight_objs PUBLIC hl_openexr)
endif()
