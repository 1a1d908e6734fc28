// Plain-old-data byte streams, as the host lays the values out (theia
// targets little-endian x86-64 and arm64).
#pragma once

#include "core/log.h"

#include <cstdint>
#include <cstring>
#include <span>
#include <string>
#include <type_traits>
#include <vector>

namespace theia {

// Little-endian plain-old-data (de)serialisation (checkpoint sections, the saved guiding field).
struct ByteWriter {
  std::vector<uint8_t> bytes;
  template <typename T>
  void put(const T& v) {
    static_assert(std::is_trivially_copyable_v<T>);
    const auto* p = reinterpret_cast<const uint8_t*>(&v);
    bytes.insert(bytes.end(), p, p + sizeof(T));
  }
  template <typename T>
  void put_vector(const std::vector<T>& v) {
    put<uint64_t>(v.size());
    const auto* p = reinterpret_cast<const uint8_t*>(v.data());
    bytes.insert(bytes.end(), p, p + v.size() * sizeof(T));
  }
  void put_string(const std::string& s) { put_vector(std::vector<char>(s.begin(), s.end())); }
};

// Reads what ByteWriter wrote; throws theia::Error("<what>: truncated") past the end.
struct ByteReader {
  const uint8_t* data;
  size_t size, pos = 0;
  std::string what;
  ByteReader(const std::vector<uint8_t>& b, std::string w) : data(b.data()), size(b.size()), what(std::move(w)) {}
  ByteReader(std::span<const uint8_t> b, std::string w) : data(b.data()), size(b.size()), what(std::move(w)) {}
  void need(size_t n) const {
    if (n > size - pos) throw_error("{}: truncated (wanted {} bytes at offset {} of {})", what, n, pos, size);
  }
  template <typename T>
  T get() {
    need(sizeof(T));
    T v;
    std::memcpy(&v, data + pos, sizeof(T));
    pos += sizeof(T);
    return v;
  }
  template <typename T>
  std::vector<T> get_vector() {
    uint64_t n = get<uint64_t>();
    if (n > (size - pos) / sizeof(T)) need(size + 1);
    std::vector<T> v(n);
    std::memcpy(v.data(), data + pos, n * sizeof(T));
    pos += n * sizeof(T);
    return v;
  }
  std::string get_string() {
    auto v = get_vector<char>();
    return {v.begin(), v.end()};
  }
};

}  // namespace theia
