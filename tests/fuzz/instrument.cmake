# With OCCGEO_FUZZ=ON every target of the project is compiled with libFuzzer's coverage
# instrumentation and ASan + UBSan (any sanitizer report aborts), so a fuzz target sees into the
# libraries it calls. Only the fuzz targets themselves link libFuzzer's main (tests/fuzz).
if(OCCGEO_FUZZ)
  if(NOT CMAKE_CXX_COMPILER_ID STREQUAL "Clang")
    message(FATAL_ERROR "OCCGEO_FUZZ=ON needs clang (libFuzzer): configure with CXX=clang++")
  endif()
  set(OCCGEO_SANITIZERS -fsanitize=address,undefined -fno-sanitize-recover=all)
  add_compile_options(${OCCGEO_SANITIZERS} -fsanitize=fuzzer-no-link -fno-omit-frame-pointer)
  add_link_options(${OCCGEO_SANITIZERS})
endif()
