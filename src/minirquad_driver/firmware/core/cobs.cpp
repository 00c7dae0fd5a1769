#include "cobs.h"

namespace mrq {

size_t cobs_encode(const uint8_t* in, size_t n, uint8_t* out, size_t cap) {
  // Worst case: one code byte per 254 data bytes, plus one.
  if (cap < n + n / 254 + 1) return 0;
  size_t code_at = 0;   // where the current block's code byte goes
  size_t o = 1;
  uint8_t code = 1;
  bool closed_full = false;
  for (size_t i = 0; i < n; ++i) {
    closed_full = false;
    if (in[i] == 0) {
      out[code_at] = code;
      code_at = o++;
      code = 1;
      continue;
    }
    out[o++] = in[i];
    if (++code == 0xFF) {   // 254 data bytes: close the block, no implied zero
      out[code_at] = code;
      code_at = o++;
      code = 1;
      closed_full = true;
    }
  }
  if (closed_full) return o - 1;   // the block just opened stays unused
  out[code_at] = code;
  return o;
}

bool cobs_decode(const uint8_t* in, size_t n, uint8_t* out, size_t cap, size_t* out_len) {
  if (n == 0 || cap < n) return false;
  size_t i = 0;
  size_t o = 0;
  while (i < n) {
    const uint8_t code = in[i];
    if (code == 0) return false;
    const size_t end = i + code;
    if (end > n) return false;
    for (size_t k = i + 1; k < end; ++k) {
      if (in[k] == 0) return false;
      out[o++] = in[k];
    }
    i = end;
    // A code below 0xFF stands for "block, then a zero" unless it ends the segment.
    if (code < 0xFF && i < n) out[o++] = 0;
  }
  *out_len = o;
  return true;
}

}  // namespace mrq
