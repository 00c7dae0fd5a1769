// The C++ decoder as a filter, for differential tests against the Python codec.
// stdin: records of [u32 little-endian length][bytes]; each record is decoded by a fresh
// decoder. stdout, per record: one line "F <type> <seq> <t_ms> <payload hex or ->" per frame,
// then "C <frames> <cobs> <crc> <short> <version> <unknown> <payload> <range> <overflow>
// <bytes_in>".
#include <stdio.h>
#include <stdlib.h>

#include <vector>

#include "../core/frame.h"

int main() {
  std::vector<unsigned char> rec;
  unsigned char len_bytes[4];
  while (fread(len_bytes, 1, 4, stdin) == 4) {
    const size_t n = size_t(len_bytes[0]) | (size_t(len_bytes[1]) << 8) |
                     (size_t(len_bytes[2]) << 16) | (size_t(len_bytes[3]) << 24);
    rec.resize(n);
    if (n && fread(&rec[0], 1, n, stdin) != n) return 2;
    mrq::FrameDecoder dec;
    mrq::Frame f;
    for (size_t i = 0; i < n; ++i) {
      if (!dec.push(rec[i], &f)) continue;
      uint8_t payload[mrq::MAX_FRAME];
      const int len = mrq::pack_payload(f.message, payload, sizeof(payload));
      printf("F %u %u %u ", unsigned(f.message.type), unsigned(f.seq), unsigned(f.t_ms));
      if (len <= 0) printf("-");
      for (int k = 0; k < len; ++k) printf("%02x", payload[k]);
      printf("\n");
    }
    const mrq::DecoderStats& s = dec.stats();
    printf("C %u %u %u %u %u %u %u %u %u %u\n", s.frames, s.cobs_errors, s.crc_errors,
           s.short_frames, s.version_errors, s.unknown_types, s.payload_errors, s.range_errors,
           s.overflows, s.bytes_in);
  }
  return 0;
}
