# Compiler warnings, hardening, sanitizers and board CPU flags applied to every dentmark target.
add_library(dentmark_options INTERFACE)
target_compile_options(dentmark_options INTERFACE
  -Wall -Wextra -Wpedantic -Wshadow -Wnon-virtual-dtor -Wcast-align -Woverloaded-virtual
  -Wformat=2 -Wimplicit-fallthrough)
if(DENTMARK_WERROR)
  target_compile_options(dentmark_options INTERFACE -Werror)
endif()
if(DENTMARK_SANITIZE)
  target_compile_options(dentmark_options INTERFACE -fsanitize=address,undefined -fno-omit-frame-pointer
                                                    -fno-sanitize-recover=undefined)
  target_link_options(dentmark_options INTERFACE -fsanitize=address,undefined)
endif()

# Debian 12's hardening flags (dpkg-buildflags with hardening=+all; its compiler makes
# position-independent executables by default) on every build that may be shipped:
# not the sanitizer or fuzzing builds, which instrument the same places themselves.
# _FORTIFY_SOURCE needs the optimiser, so Debug builds go without it.
if(NOT DENTMARK_SANITIZE AND NOT DENTMARK_FUZZ)
  target_compile_options(dentmark_options INTERFACE -fstack-protector-strong -Werror=format-security)
  target_compile_definitions(dentmark_options INTERFACE $<$<NOT:$<CONFIG:Debug>>:_FORTIFY_SOURCE=2>)
  target_link_options(dentmark_options INTERFACE LINKER:-z,relro LINKER:-z,now)
endif()

if(CMAKE_CROSSCOMPILING)
  set(_board_cmake "${PROJECT_SOURCE_DIR}/boards/${DENTMARK_BOARD}/board.cmake")
  if(NOT EXISTS "${_board_cmake}")
    message(FATAL_ERROR "DENTMARK_BOARD=${DENTMARK_BOARD}: no ${_board_cmake}")
  endif()
  include("${_board_cmake}")
  separate_arguments(_board_flags UNIX_COMMAND "${DENTMARK_BOARD_CPU_FLAGS}")
  target_compile_options(dentmark_options INTERFACE ${_board_flags})
  message(STATUS "dentmark: board ${DENTMARK_BOARD}, CPU flags '${DENTMARK_BOARD_CPU_FLAGS}'")
endif()

# Line tables only: CI machines may have little disk (a full-debug host tree is 1.8 GB).
# A directory option, so it follows CMAKE_CXX_FLAGS_<CONFIG>'s -g on every command line.
if(DENTMARK_DEBUG_INFO STREQUAL "lines")
  add_compile_options(-g1)
elseif(NOT DENTMARK_DEBUG_INFO STREQUAL "full")
  message(FATAL_ERROR "DENTMARK_DEBUG_INFO=${DENTMARK_DEBUG_INFO}: expected full or lines")
endif()
