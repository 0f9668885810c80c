# Cross toolchain for the edge box: Debian's aarch64-linux-gnu GCC against an arm64
# sysroot extracted from Debian's arm64 packages (scripts/setup-deps).
# The sysroot is taken from -DDENTMARK_SYSROOT=..., else $DENTMARK_SYSROOT,
# else ~/.cache/dentmark/sysroot-arm64.
set(CMAKE_SYSTEM_NAME Linux)
set(CMAKE_SYSTEM_PROCESSOR aarch64)
set(CMAKE_LIBRARY_ARCHITECTURE aarch64-linux-gnu)

set(CMAKE_C_COMPILER aarch64-linux-gnu-gcc)
set(CMAKE_CXX_COMPILER aarch64-linux-gnu-g++)

if(NOT DENTMARK_SYSROOT)
  if(DEFINED ENV{DENTMARK_SYSROOT} AND NOT "$ENV{DENTMARK_SYSROOT}" STREQUAL "")
    set(DENTMARK_SYSROOT "$ENV{DENTMARK_SYSROOT}")
  else()
    set(DENTMARK_SYSROOT "$ENV{HOME}/.cache/dentmark/sysroot-arm64")
  endif()
endif()
set(DENTMARK_SYSROOT "${DENTMARK_SYSROOT}" CACHE PATH "arm64 sysroot (scripts/setup-deps makes it)")
if(NOT EXISTS "${DENTMARK_SYSROOT}/usr/lib/aarch64-linux-gnu")
  message(FATAL_ERROR "No arm64 sysroot at ${DENTMARK_SYSROOT}: run scripts/setup-deps")
endif()
# try_compile projects see the same sysroot.
list(APPEND CMAKE_TRY_COMPILE_PLATFORM_VARIABLES DENTMARK_SYSROOT)

set(CMAKE_SYSROOT "${DENTMARK_SYSROOT}")
set(CMAKE_FIND_ROOT_PATH "${DENTMARK_SYSROOT}")
# Programs come from the build host; headers, libraries and packages only from the sysroot.
set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_PACKAGE ONLY)

# pkg-config must read the sysroot's .pc files and prefix their paths with it.
set(ENV{PKG_CONFIG_DIR} "")
set(ENV{PKG_CONFIG_LIBDIR}
    "${DENTMARK_SYSROOT}/usr/lib/aarch64-linux-gnu/pkgconfig:${DENTMARK_SYSROOT}/usr/share/pkgconfig")
set(ENV{PKG_CONFIG_SYSROOT_DIR} "${DENTMARK_SYSROOT}")

# Cross-built tests run under qemu-user with the sysroot's dynamic loader and libraries.
set(CMAKE_CROSSCOMPILING_EMULATOR "qemu-aarch64;-L;${DENTMARK_SYSROOT}")
