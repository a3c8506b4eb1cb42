#pragma once

// Plain values to and from bytes, for the state a tracker saves into a checkpoint so that a
// resumed run goes on exactly where the first one stopped (docs/reliability.md, "Resume").
// Little-endian host layout, bit for bit (doubles round-trip exactly); the reader never reads
// past the end: every Get fails once the bytes run out.

#include <Eigen/Core>

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string>
#include <type_traits>
#include <vector>

namespace saker {

class ByteWriter {
 public:
  template <typename T>
  void Put(T value) {
    static_assert(std::is_arithmetic_v<T>);
    const size_t at = bytes_.size();
    bytes_.resize(at + sizeof(T));
    std::memcpy(bytes_.data() + at, &value, sizeof(T));
  }
  // Rows one after another.
  template <typename Derived>
  void PutMatrix(const Eigen::MatrixBase<Derived>& m) {
    for (Eigen::Index r = 0; r < m.rows(); ++r) {
      for (Eigen::Index c = 0; c < m.cols(); ++c) Put<double>(m(r, c));
    }
  }
  // A count, then the items (arithmetic).
  template <typename T>
  void PutVector(const std::vector<T>& items) {
    Put<uint64_t>(items.size());
    for (const T& item : items) Put<T>(item);
  }
  // A count, then the bytes.
  void PutBytes(const uint8_t* data, size_t size) {
    Put<uint64_t>(size);
    bytes_.insert(bytes_.end(), data, data + size);
  }
  void PutString(const std::string& s) {
    PutBytes(reinterpret_cast<const uint8_t*>(s.data()), s.size());
  }
  const std::vector<uint8_t>& bytes() const { return bytes_; }
  std::vector<uint8_t> Take() { return std::move(bytes_); }

 private:
  std::vector<uint8_t> bytes_;
};

class ByteReader {
 public:
  explicit ByteReader(const std::vector<uint8_t>& bytes) : bytes_(bytes) {}

  template <typename T>
  bool Get(T* value) {
    static_assert(std::is_arithmetic_v<T>);
    if (bytes_.size() - at_ < sizeof(T)) return false;
    std::memcpy(value, bytes_.data() + at_, sizeof(T));
    at_ += sizeof(T);
    return true;
  }
  template <typename Matrix>
  bool GetMatrix(Matrix* m) {
    for (Eigen::Index r = 0; r < m->rows(); ++r) {
      for (Eigen::Index c = 0; c < m->cols(); ++c) {
        if (!Get(&(*m)(r, c))) return false;
      }
    }
    return true;
  }
  // A count of items of at least `item_bytes` each that the rest of the bytes can hold.
  bool GetCount(size_t item_bytes, size_t* count) {
    uint64_t n = 0;
    if (!Get(&n) || n > (bytes_.size() - at_) / item_bytes) return false;
    *count = static_cast<size_t>(n);
    return true;
  }
  template <typename T>
  bool GetVector(std::vector<T>* items) {
    size_t n = 0;
    if (!GetCount(sizeof(T), &n)) return false;
    items->resize(n);
    for (T& item : *items) {
      if (!Get(&item)) return false;
    }
    return true;
  }
  bool GetBytes(std::vector<uint8_t>* out) {
    size_t n = 0;
    if (!GetCount(1, &n)) return false;
    out->assign(bytes_.begin() + static_cast<std::ptrdiff_t>(at_),
                bytes_.begin() + static_cast<std::ptrdiff_t>(at_ + n));
    at_ += n;
    return true;
  }
  bool GetString(std::string* out) {
    size_t n = 0;
    if (!GetCount(1, &n)) return false;
    out->assign(reinterpret_cast<const char*>(bytes_.data() + at_), n);
    at_ += n;
    return true;
  }
  bool AtEnd() const { return at_ == bytes_.size(); }

 private:
  const std::vector<uint8_t>& bytes_;
  size_t at_ = 0;
};

}  // namespace saker
