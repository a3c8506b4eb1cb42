#include "core/util/status.h"

#include <exception>
#include <new>

namespace saker {

const char* StatusCodeName(StatusCode code) {
  switch (code) {
    case StatusCode::kOk:
      return "OK";
    case StatusCode::kInvalidArgument:
      return "InvalidArgument";
    case StatusCode::kNotFound:
      return "NotFound";
    case StatusCode::kInvalidData:
      return "InvalidData";
    case StatusCode::kUnsupported:
      return "Unsupported";
    case StatusCode::kIoError:
      return "IoError";
    case StatusCode::kCancelled:
      return "Cancelled";
    case StatusCode::kOutOfRange:
      return "OutOfRange";
    case StatusCode::kResourceExhausted:
      return "ResourceExhausted";
    case StatusCode::kInternal:
      return "Internal";
  }
  return "Unknown";
}

std::string Status::ToString() const {
  if (ok()) return "OK";
  return std::string(StatusCodeName(code_)) + ": " + message_;
}

Status StatusFromCurrentException(const std::string& context) {
  const std::string prefix = context.empty() ? std::string() : context + ": ";
  const Status out_of_memory = ResourceExhaustedError(
      prefix + "out of memory (free memory, or process a shorter part of the video)");
  const std::exception_ptr current = std::current_exception();
  if (!current) return InternalError(prefix + "no exception to report (a bug)");
  try {
    std::rethrow_exception(current);
  } catch (const std::bad_alloc&) {
    return out_of_memory;
  } catch (const std::exception& e) {
    // Memory, recognised by the text (util links no OpenCV): OpenCV's failed allocation
    // (cv::Exception "(-4:Insufficient memory)"), and a thread that could not be started
    // (std::system_error from std::thread, std::runtime_error from OpenCV's thread pool, both
    // with strerror(EAGAIN) or strerror(ENOMEM)).
    const std::string what = e.what();
    for (const char* marker :
         {"Insufficient memory", "Resource temporarily unavailable", "Cannot allocate memory"}) {
      if (what.find(marker) != std::string::npos) return out_of_memory;
    }
    return InternalError(prefix + "unexpected error (a bug, please report it): " + what);
  } catch (...) {
    return InternalError(prefix + "unexpected error of an unknown kind (a bug, please report it)");
  }
}

}  // namespace saker
