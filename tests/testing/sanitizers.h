// Which sanitizer a test executable is built with (the asan and tsan presets), for the few tests
// that do less under one: a whole flight costs minutes there, and the same code paths already run
// under it in another test.

#ifndef SAKER_TESTS_TESTING_SANITIZERS_H_
#define SAKER_TESTS_TESTING_SANITIZERS_H_

namespace saker::testing {

#if defined(__SANITIZE_THREAD__)
inline constexpr bool kUnderThreadSanitizer = true;
#else
inline constexpr bool kUnderThreadSanitizer = false;
#endif

#if defined(__SANITIZE_ADDRESS__)
inline constexpr bool kUnderAddressSanitizer = true;
#else
inline constexpr bool kUnderAddressSanitizer = false;
#endif

}  // namespace saker::testing

// Skips the current test under ThreadSanitizer, saying which test covers its threads instead.
#define SAKER_SKIP_UNDER_TSAN(covered_by)                                          \
  do {                                                                             \
    if constexpr (::saker::testing::kUnderThreadSanitizer) {                       \
      GTEST_SKIP() << "its threads run under ThreadSanitizer in " << (covered_by); \
    }                                                                              \
  } while (false)

// Skips the current test under AddressSanitizer (a whole flight's accuracy run, minutes there),
// saying which test runs its code paths under it instead.
#define SAKER_SKIP_UNDER_ASAN(covered_by)                                         \
  do {                                                                            \
    if constexpr (::saker::testing::kUnderAddressSanitizer) {                     \
      GTEST_SKIP() << "an accuracy run over a whole flight; its code runs under " \
                      "AddressSanitizer in "                                      \
                   << (covered_by);                                               \
    }                                                                             \
  } while (false)

#endif  // SAKER_TESTS_TESTING_SANITIZERS_H_
