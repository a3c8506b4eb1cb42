#pragma once

// SAKER_CHECK(cond) << "context";  for broken invariants (bugs). It throws
// saker::CheckError naming file and line, so a GUI process can report the bug
// and keep the operator's work instead of aborting.

#include <sstream>
#include <stdexcept>
#include <string>

namespace saker {

class CheckError : public std::logic_error {
 public:
  using std::logic_error::logic_error;
};

namespace internal {

// Collects the streamed message and throws when destroyed at the end of the
// full expression. Only ever constructed when the check has failed.
class CheckFailure {
 public:
  CheckFailure(const char* file, int line, const char* condition) {
    stream_ << file << ":" << line << ": check failed: " << condition;
  }
  CheckFailure(const CheckFailure&) = delete;
  CheckFailure& operator=(const CheckFailure&) = delete;
  [[noreturn]] ~CheckFailure() noexcept(false) { throw CheckError(stream_.str()); }

  template <typename T>
  CheckFailure& operator<<(const T& value) {
    if (!has_message_) stream_ << ": ";
    has_message_ = true;
    stream_ << value;
    return *this;
  }

 private:
  std::ostringstream stream_;
  bool has_message_ = false;
};

// Lets `SAKER_CHECK(x) << ...` be a single expression of type void.
struct Voidify {
  void operator&(const CheckFailure&) {}
};

}  // namespace internal
}  // namespace saker

#define SAKER_CHECK(condition)                 \
  (condition) ? (void)0                        \
              : ::saker::internal::Voidify() & \
                    ::saker::internal::CheckFailure(__FILE__, __LINE__, #condition)
