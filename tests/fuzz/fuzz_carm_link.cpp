// The C-arm link byte stream (COBS frames, CRC-32): the decoder never throws or crashes,
// and how the stream is chunked does not change what it delivers.
#include <cmath>

#include "evar/acquisition/carm_link_protocol.hpp"
#include "fuzz_input.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  namespace link = evar::acquisition::carm_link;
  link::Decoder decoder;
  std::size_t messages = 0;
  // Fed in two chunks split where the first byte says: chunking must not matter.
  const std::size_t cut = size > 0 ? data[0] % (size + 1) : 0;
  const auto count = [&](const link::Message&) { ++messages; };
  decoder.feed({data, cut}, count);
  decoder.feed({data + cut, size - cut}, count);
  link::Decoder whole;
  std::size_t whole_messages = 0;
  whole.feed({data, size}, [&](const link::Message&) { ++whole_messages; });
  if (whole_messages != messages || whole.stats().errors() != decoder.stats().errors()) {
    std::fprintf(stderr, "chunking changed the result: %zu/%zu messages\n", messages, whole_messages);
    std::abort();
  }
  return 0;
}
