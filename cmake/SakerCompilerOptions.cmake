# Warnings and sanitizers for every Saker target, applied through one
# interface target so third-party code is left alone.
add_library(saker_compile_options INTERFACE)
target_compile_options(saker_compile_options INTERFACE
  -Wall -Wextra -Wpedantic -Wshadow -Wnon-virtual-dtor -Wcast-align
  -Woverloaded-virtual -Wimplicit-fallthrough)

if(SAKER_SANITIZE AND SAKER_SANITIZE_THREAD)
  # The runtimes of ASan and TSan cannot share one process.
  message(FATAL_ERROR "SAKER_SANITIZE and SAKER_SANITIZE_THREAD are mutually exclusive")
endif()
if(SAKER_SANITIZE)
  # UBSan's null and alignment checks are left out: they guard every reference Eigen's inlined
  # expression templates bind, and cost a third of the build's compile time (homography.cc: 43 s
  # against 63 s) while finding nothing ASan misses here: a null dereference is an ASan SEGV
  # report, and x86-64 loads unaligned data correctly (the KLV and TS parsers read byte by byte).
  target_compile_options(saker_compile_options INTERFACE
    -fsanitize=address,undefined -fno-sanitize=null,alignment -fno-omit-frame-pointer
    -fno-sanitize-recover=undefined)
  target_link_options(saker_compile_options INTERFACE -fsanitize=address,undefined)
  # Eigen stops trusting malloc's 16-byte alignment when it sees __SANITIZE_ADDRESS__ and then
  # offsets its blocks by hand, while the prebuilt Ceres frees the Eigen matrices it receives
  # with plain free(): a bad-free in every covariance. glibc's and ASan's malloc both align to
  # 16 bytes on x86-64, so tell Eigen so and match Ceres's build.
  target_compile_definitions(saker_compile_options INTERFACE EIGEN_MALLOC_ALREADY_ALIGNED=1)
endif()
if(SAKER_SANITIZE_THREAD)
  # Only our code is instrumented (Qt, OpenCV and FFmpeg are not): what they synchronise
  # internally with their own atomics TSan cannot see; tests/sanitizers/tsan.supp lists the
  # few such reports, each with its reason.
  target_compile_options(saker_compile_options INTERFACE -fsanitize=thread -fno-omit-frame-pointer)
  target_link_options(saker_compile_options INTERFACE -fsanitize=thread)
endif()

# LLVM's linker links a test executable about five times faster than GNU ld (0.7 s against 3.3 s
# for test_mosaic_chain_solver in the release tree): the suite has about 140 executables.
option(SAKER_USE_LLD "Link with lld when the compiler accepts -fuse-ld=lld" ON)
if(SAKER_USE_LLD)
  include(CheckLinkerFlag)
  check_linker_flag(CXX -fuse-ld=lld SAKER_HAVE_LLD)
  if(SAKER_HAVE_LLD)
    add_link_options(-fuse-ld=lld)
  endif()
endif()

find_program(CCACHE_PROGRAM ccache)
if(CCACHE_PROGRAM)
  set(CMAKE_CXX_COMPILER_LAUNCHER ${CCACHE_PROGRAM})
endif()

# saker_add_library(name SOURCES ... DEPS ...): one static library per stage.
function(saker_add_library name)
  cmake_parse_arguments(ARG "" "" "SOURCES;PUBLIC_DEPS;PRIVATE_DEPS" ${ARGN})
  add_library(${name} STATIC ${ARG_SOURCES})
  target_include_directories(${name} PUBLIC ${PROJECT_SOURCE_DIR})
  target_link_libraries(${name} PUBLIC ${ARG_PUBLIC_DEPS} PRIVATE saker_compile_options ${ARG_PRIVATE_DEPS})
  set_property(GLOBAL APPEND PROPERTY SAKER_LIBRARIES ${name})
endfunction()
