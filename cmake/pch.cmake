# A precompiled header for the test programs (GCC and Clang): the standard and third-party
# headers most test files include (GoogleTest, Eigen, OpenCV's core, nlohmann/json) are parsed
# once per build instead of once per file, where they took about 6 of a test file's 8.5 s of
# compilation: the test files' compilation went from 657 to 542 s of CPU (a clean release build
# on 2 cores). The libraries' files gain nothing measurable from one (their time is code
# generation: 655 against 674 s), so they have none. Every test reuses the one host's header; under -Werror a header GCC
# could not use fails the build (-Winvalid-pch), so a mismatch never passes silently. Clang (the
# fuzz preset's ASan + UBSan tests) uses it too: their compilation 345 -> 244 s of CPU.
# MCSLAM_PCH=OFF compiles without it.
option(MCSLAM_PCH "Precompile the test programs' common headers (GCC and Clang)" ON)
set(MCSLAM_USE_PCH OFF)
if(MCSLAM_PCH AND CMAKE_CXX_COMPILER_ID MATCHES "GNU|Clang")
  set(MCSLAM_USE_PCH ON)
endif()

# mcslam_pch_host(NAME HEADERS... [LIBS ...]): a program that only builds the precompiled header
# the test programs reuse (with their code-generation flags: -fPIE).
function(mcslam_pch_host name)
  cmake_parse_arguments(P "" "" "HEADERS;LIBS" ${ARGN})
  set(source ${CMAKE_CURRENT_BINARY_DIR}/${name}.cpp)
  file(WRITE ${source} "// The host of a precompiled header (cmake/pch.cmake).\nint main() { return 0; }\n")
  add_executable(${name} ${source})
  target_link_libraries(${name} PRIVATE mcslam_build_flags Eigen3::Eigen opencv_core opencv_imgproc
                                        nlohmann_json::nlohmann_json ${P_LIBS})
  target_precompile_headers(${name} PRIVATE ${P_HEADERS})
endfunction()
