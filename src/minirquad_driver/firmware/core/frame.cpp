#include "frame.h"

#include <string.h>

#include "cobs.h"
#include "crc16.h"
#include "wire.h"

namespace mrq {

FrameDecoder::FrameDecoder() : len_(0), skipping_(false) { memset(&stats_, 0, sizeof(stats_)); }

void FrameDecoder::reset() {
  len_ = 0;
  skipping_ = false;
}

bool FrameDecoder::push(uint8_t byte, Frame* out) {
  ++stats_.bytes_in;
  if (byte != 0) {
    if (skipping_) return false;
    if (len_ == MAX_ENCODED) {   // no delimiter within the longest legal encoding
      ++stats_.overflows;
      len_ = 0;
      skipping_ = true;
      return false;
    }
    buf_[len_++] = byte;
    return false;
  }
  // A delimiter ends the segment; empty segments (between two zeros) are ignored.
  if (skipping_) {
    skipping_ = false;
    return false;
  }
  if (len_ == 0) return false;
  const bool ok = decode_segment(out);
  len_ = 0;
  return ok;
}

bool FrameDecoder::decode_segment(Frame* out) {
  size_t n = 0;
  if (!cobs_decode(buf_, len_, buf_, sizeof(buf_), &n)) {   // in place
    ++stats_.cobs_errors;
    return false;
  }
  if (n < HEADER_SIZE + CRC_SIZE) {
    ++stats_.short_frames;
    return false;
  }
  const uint16_t crc = get_u16(buf_ + n - CRC_SIZE);
  if (crc16_ccitt_false(buf_, n - CRC_SIZE) != crc) {
    ++stats_.crc_errors;
    return false;
  }
  if (buf_[0] != PROTOCOL_VERSION) {
    ++stats_.version_errors;
    return false;
  }
  const uint8_t type = buf_[1];
  if (!is_known_type(type)) {
    ++stats_.unknown_types;
    return false;
  }
  const PayloadStatus st = unpack_payload(type, buf_ + HEADER_SIZE, n - HEADER_SIZE - CRC_SIZE,
                                          &out->message);
  if (st == PAYLOAD_RANGE) {
    ++stats_.range_errors;
    return false;
  }
  if (st != PAYLOAD_OK) {
    ++stats_.payload_errors;
    return false;
  }
  out->seq = buf_[2];
  out->t_ms = get_u32(buf_ + 3);
  ++stats_.frames;
  return true;
}

size_t encode_frame(const Message& msg, uint8_t seq, uint32_t t_ms, uint8_t* out, size_t cap) {
  if (cap < MAX_WIRE) return 0;
  uint8_t body[MAX_FRAME];
  body[0] = PROTOCOL_VERSION;
  body[1] = msg.type;
  body[2] = seq;
  put_u32(body + 3, t_ms);
  const int n = pack_payload(msg, body + HEADER_SIZE, MAX_FRAME - HEADER_SIZE - CRC_SIZE);
  if (n < 0) return 0;
  const size_t len = HEADER_SIZE + size_t(n);
  put_u16(body + len, crc16_ccitt_false(body, len));
  out[0] = 0;
  const size_t enc = cobs_encode(body, len + CRC_SIZE, out + 1, cap - 2);
  if (enc == 0) return 0;
  out[1 + enc] = 0;
  return enc + 2;
}

}  // namespace mrq
