include(GoogleTest)

# dentmark_add_test(<name> SOURCES ... LIBS ...)
# A GoogleTest executable whose cases are discovered when ctest runs (PRE_TEST), so
# cross builds never execute target binaries at build time.
# REAL_TIME: the program's tests hold real-time bounds (an e-stop closes the valve within
# 10 ms of wall time); they run alone, not beside a detection test that keeps both cores
# busy.
function(dentmark_add_test name)
  cmake_parse_arguments(ARG "REAL_TIME" "TIMEOUT" "SOURCES;LIBS;LABELS" ${ARGN})
  add_executable(${name} ${ARG_SOURCES})
  target_link_libraries(${name} PRIVATE ${ARG_LIBS} GTest::gtest GTest::gtest_main GTest::gmock dentmark_options)
  target_compile_definitions(${name} PRIVATE DENTMARK_SOURCE_DIR="${PROJECT_SOURCE_DIR}"
                                             DENTMARK_TEST_DATA_DIR="${PROJECT_SOURCE_DIR}/tests/data")
  if(NOT ARG_TIMEOUT)
    set(ARG_TIMEOUT 300)
  endif()
  # Sanitized -O0 builds run the big-scan detection tests 10-20 times slower: 200-300 s
  # each on a loaded 2-core machine.
  if(DENTMARK_SANITIZE)
    math(EXPR ARG_TIMEOUT "${ARG_TIMEOUT} * 3")
  endif()
  set(properties TIMEOUT ${ARG_TIMEOUT})
  if(ARG_LABELS)
    list(APPEND properties LABELS "${ARG_LABELS}")
  endif()
  if(ARG_REAL_TIME)
    list(APPEND properties RUN_SERIAL TRUE)
  endif()
  gtest_discover_tests(${name} DISCOVERY_MODE PRE_TEST DISCOVERY_TIMEOUT 120 PROPERTIES ${properties})
endfunction()

# dentmark_add_benchmark(<name> SOURCES ... LIBS ...): a Google Benchmark program (not a test).
function(dentmark_add_benchmark name)
  if(NOT DENTMARK_BUILD_BENCHMARKS)
    return()
  endif()
  cmake_parse_arguments(ARG "" "" "SOURCES;LIBS" ${ARGN})
  add_executable(${name} ${ARG_SOURCES})
  target_link_libraries(${name} PRIVATE ${ARG_LIBS} benchmark::benchmark benchmark::benchmark_main dentmark_options)
endfunction()

# dentmark_add_command_test(<name> TARGET <exe> ARGS ... EXPECT_CODE n [EXPECT_REGEX re] [EXPECT_LINES n])
# Runs one of our executables (under the cross emulator when cross-compiling) and
# checks exit code and output.
function(dentmark_add_command_test name)
  cmake_parse_arguments(ARG "" "TARGET;EXPECT_CODE;EXPECT_REGEX;EXPECT_LINES" "ARGS" ${ARGN})
  set(cmd ${CMAKE_CROSSCOMPILING_EMULATOR} $<TARGET_FILE:${ARG_TARGET}> ${ARG_ARGS})
  string(REPLACE ";" "|" cmd_escaped "${cmd}")
  set(extra)
  if(DEFINED ARG_EXPECT_REGEX)
    list(APPEND extra "-DEXPECT_REGEX=${ARG_EXPECT_REGEX}")
  endif()
  if(DEFINED ARG_EXPECT_LINES)
    list(APPEND extra "-DEXPECT_LINES=${ARG_EXPECT_LINES}")
  endif()
  add_test(NAME ${name}
           COMMAND ${CMAKE_COMMAND} "-DCMD=${cmd_escaped}" -DEXPECT_CODE=${ARG_EXPECT_CODE} ${extra}
                   -P ${PROJECT_SOURCE_DIR}/tests/cmake/expect_command.cmake)
  set_tests_properties(${name} PROPERTIES TIMEOUT 180)
endfunction()
