#pragma once

// Expected failures (a missing file, a corrupt packet, a bad checksum) are
// returned as values, never thrown: the caller decides whether to go on.
// Broken invariants (bugs) use SAKER_CHECK from core/util/check.h instead.

#include "core/util/check.h"

#include <optional>
#include <string>
#include <utility>
#include <variant>

namespace saker {

// Broad class of an expected failure, so callers can react without parsing text.
enum class StatusCode {
  kOk = 0,
  kInvalidArgument,    // The caller passed something unusable (bad option, bad index).
  kNotFound,           // A file, stream or item does not exist.
  kInvalidData,        // Input exists but is malformed (corrupt packet, not a video).
  kUnsupported,        // Valid input that this build cannot handle.
  kIoError,            // The operating system or a library failed to read or write.
  kCancelled,          // The job was cancelled by the user.
  kOutOfRange,         // Seek or lookup past the end.
  kResourceExhausted,  // A configured limit (memory, size) would be exceeded, or memory ran out.
  kInternal,           // An unexpected exception (a bug) caught at a thread or process boundary.
};

const char* StatusCodeName(StatusCode code);

// The result of an operation that can fail for reasons outside our control.
// The message is written for a person: it names the file and the problem.
class [[nodiscard]] Status {
 public:
  Status() = default;
  Status(StatusCode code, std::string message) : code_(code), message_(std::move(message)) {}

  static Status Ok() { return Status(); }

  bool ok() const { return code_ == StatusCode::kOk; }
  StatusCode code() const { return code_; }
  const std::string& message() const { return message_; }
  // "InvalidData: h264.ts: not a video file" style text for logs and CLI output.
  std::string ToString() const;

 private:
  StatusCode code_ = StatusCode::kOk;
  std::string message_;
};

inline Status InvalidArgumentError(std::string m) {
  return {StatusCode::kInvalidArgument, std::move(m)};
}
inline Status NotFoundError(std::string m) { return {StatusCode::kNotFound, std::move(m)}; }
inline Status InvalidDataError(std::string m) { return {StatusCode::kInvalidData, std::move(m)}; }
inline Status UnsupportedError(std::string m) { return {StatusCode::kUnsupported, std::move(m)}; }
inline Status IoError(std::string m) { return {StatusCode::kIoError, std::move(m)}; }
inline Status CancelledError(std::string m) { return {StatusCode::kCancelled, std::move(m)}; }
inline Status OutOfRangeError(std::string m) { return {StatusCode::kOutOfRange, std::move(m)}; }
inline Status InternalError(std::string m) { return {StatusCode::kInternal, std::move(m)}; }
inline Status ResourceExhaustedError(std::string m) {
  return {StatusCode::kResourceExhausted, std::move(m)};
}

// A value or the Status explaining why there is none.
template <typename T>
class [[nodiscard]] StatusOr {
 public:
  StatusOr(T value) : data_(std::move(value)) {}        // NOLINT: implicit by design.
  StatusOr(Status status) : data_(std::move(status)) {  // NOLINT: implicit by design.
    SAKER_CHECK(!std::get<Status>(data_).ok()) << "StatusOr built from an OK status";
  }

  bool ok() const { return std::holds_alternative<T>(data_); }
  const Status& status() const {
    static const Status kOk;
    return ok() ? kOk : std::get<Status>(data_);
  }
  const T& value() const& {
    SAKER_CHECK(ok()) << "value() on error: " << status().ToString();
    return std::get<T>(data_);
  }
  T& value() & {
    SAKER_CHECK(ok()) << "value() on error: " << status().ToString();
    return std::get<T>(data_);
  }
  T&& value() && {
    SAKER_CHECK(ok()) << "value() on error: " << status().ToString();
    return std::get<T>(std::move(data_));
  }
  const T& operator*() const& { return value(); }
  T& operator*() & { return value(); }
  const T* operator->() const { return &value(); }
  T* operator->() { return &value(); }

 private:
  std::variant<T, Status> data_;
};

// The Status for the exception being handled: call it in a `catch (...)` block where an exception
// must not go further (a thread's or a process's outermost frame, the engine's boundary).
// ResourceExhausted ("out of memory") for std::bad_alloc, OpenCV's failed allocations and a
// thread that could not be started; kInternal (a bug), with the exception's text, for any other.
// `context` starts the message (the file or the job).
Status StatusFromCurrentException(const std::string& context);

}  // namespace saker

// Returns early from the enclosing function when `expr` (a Status) is not OK.
#define SAKER_RETURN_IF_ERROR(expr)                \
  do {                                             \
    ::saker::Status saker_status_ = (expr);        \
    if (!saker_status_.ok()) return saker_status_; \
  } while (false)

#define SAKER_STATUS_CONCAT_INNER_(a, b) a##b
#define SAKER_STATUS_CONCAT_(a, b) SAKER_STATUS_CONCAT_INNER_(a, b)
// `lhs = value of expr` (a StatusOr), or returns its Status from the enclosing function.
// `lhs` may declare a variable: SAKER_ASSIGN_OR_RETURN(auto x, MakeX());
#define SAKER_ASSIGN_OR_RETURN(lhs, expr)                            \
  auto SAKER_STATUS_CONCAT_(saker_statusor_, __LINE__) = (expr);     \
  if (!SAKER_STATUS_CONCAT_(saker_statusor_, __LINE__).ok())         \
    return SAKER_STATUS_CONCAT_(saker_statusor_, __LINE__).status(); \
  lhs = std::move(SAKER_STATUS_CONCAT_(saker_statusor_, __LINE__)).value()
