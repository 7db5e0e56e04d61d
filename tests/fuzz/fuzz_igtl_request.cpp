// The OpenIGTLink byte stream a client sends the node's server: the reader never crashes,
// holds no more than one request's worth of bytes, and how the stream is chunked does not
// change the messages it reads or its verdict.
#include <cstdio>
#include <cstdlib>
#include <vector>

#include "igtl_request_reader.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using evar::overlay::IgtlMessageHeader;
  using evar::overlay::IgtlRequestReader;
  // Fed in two chunks split where the first byte says, and whole.
  const std::size_t cut = size > 0 ? data[0] % (size + 1) : 0;
  IgtlRequestReader chunked, whole;
  std::vector<IgtlMessageHeader> a, b;
  chunked.feed(data, cut, a);
  chunked.feed(data + cut, size - cut, a);
  whole.feed(data, size, b);
  bool same = a.size() == b.size() && chunked.garbage() == whole.garbage() && chunked.buffered() == whole.buffered();
  for (std::size_t i = 0; same && i < a.size(); ++i)
    same = a[i].type == b[i].type && a[i].device == b[i].device && a[i].body_bytes == b[i].body_bytes;
  if (!same) {
    std::fprintf(stderr, "chunking changed the result: %zu/%zu messages\n", a.size(), b.size());
    std::abort();
  }
  if (whole.buffered() >= IgtlRequestReader::kHeaderBytes + IgtlRequestReader::kMaxRequestBodyBytes) {
    std::fprintf(stderr, "the reader holds %zu bytes\n", whole.buffered());
    std::abort();
  }
  return 0;
}
