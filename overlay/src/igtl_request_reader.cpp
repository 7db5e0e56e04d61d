#include "igtl_request_reader.hpp"

#include <algorithm>

namespace evar::overlay {

namespace {

std::string header_text(const std::uint8_t* p, std::size_t n) {
  std::size_t len = 0;
  while (len < n && p[len] != 0) ++len;
  return std::string(reinterpret_cast<const char*>(p), len);
}

}  // namespace

bool IgtlRequestReader::feed(const std::uint8_t* data, std::size_t size, std::vector<IgtlMessageHeader>& out) {
  if (garbage_) return false;
  // The body of a pushed message is read past without being kept.
  const std::size_t skipped = static_cast<std::size_t>(std::min<std::uint64_t>(skip_, size));
  data += skipped;
  size -= skipped;
  skip_ -= skipped;
  in_.insert(in_.end(), data, data + size);
  std::size_t at = 0;
  for (;;) {
    if (skip_ > 0) {
      const std::size_t drop = static_cast<std::size_t>(std::min<std::uint64_t>(skip_, in_.size() - at));
      at += drop;
      skip_ -= drop;
      if (skip_ > 0) break;
    }
    if (in_.size() - at < kHeaderBytes) break;
    const std::uint8_t* h = in_.data() + at;
    IgtlMessageHeader m;
    m.type = header_text(h + 2, 12);
    m.device = header_text(h + 14, 20);
    for (int i = 0; i < 8; ++i) m.body_bytes = (m.body_bytes << 8) | h[42 + i];
    if (!m.request()) {
      at += kHeaderBytes;
      skip_ = m.body_bytes;
      out.push_back(std::move(m));
      continue;
    }
    if (m.body_bytes > kMaxRequestBodyBytes) {
      garbage_ = true;
      in_.clear();
      return false;
    }
    if (in_.size() - at < kHeaderBytes + m.body_bytes) break;
    at += kHeaderBytes + static_cast<std::size_t>(m.body_bytes);
    out.push_back(std::move(m));
  }
  in_.erase(in_.begin(), in_.begin() + static_cast<std::ptrdiff_t>(at));
  return true;
}

}  // namespace evar::overlay
