// Frames on the wire and a decoder that survives any byte stream (as protocol/codec.py).
//
//   wire:  0x00 | COBS( version:u8 | type:u8 | seq:u8 | t_ms:u32 | payload | crc16:u16 ) | 0x00
#ifndef MRQ_FRAME_H
#define MRQ_FRAME_H

#include <stddef.h>
#include <stdint.h>

#include "messages.h"

namespace mrq {

const size_t HEADER_SIZE = 7;
const size_t CRC_SIZE = 2;
const size_t MAX_FRAME = 256;                              // unstuffed body, with margin
const size_t MAX_ENCODED = MAX_FRAME + MAX_FRAME / 254 + 1;   // 258: longer segments are junk
const size_t MAX_WIRE = MAX_ENCODED + 2;                   // with both delimiters

struct Frame {
  uint8_t seq;
  uint32_t t_ms;
  Message message;
};

// Every dropped segment lands in exactly one counter.
struct DecoderStats {
  uint32_t frames;
  uint32_t bytes_in;
  uint32_t cobs_errors;
  uint32_t crc_errors;
  uint32_t short_frames;     // too short to hold header and CRC
  uint32_t version_errors;
  uint32_t unknown_types;
  uint32_t payload_errors;   // right CRC, but the payload has the wrong size or a bad value
  uint32_t range_errors;     // right size, but an enum/flag value this version lacks
  uint32_t overflows;        // a segment longer than MAX_ENCODED
};

class FrameDecoder {
 public:
  FrameDecoder();
  // Feed one byte. Returns true when it completed a valid frame, written to *out.
  bool push(uint8_t byte, Frame* out);
  // Forget a partial segment (the bytes before a reconnect belong to nothing).
  void reset();
  const DecoderStats& stats() const { return stats_; }

 private:
  bool decode_segment(Frame* out);

  uint8_t buf_[MAX_ENCODED];
  size_t len_;
  bool skipping_;   // inside an overlong segment: drop bytes until the next 0x00
  DecoderStats stats_;
};

// Encode msg as wire bytes (both delimiters) into out. Returns the length, or 0 if the
// message is invalid (see pack_payload) or cap < MAX_WIRE.
size_t encode_frame(const Message& msg, uint8_t seq, uint32_t t_ms, uint8_t* out, size_t cap);

}  // namespace mrq

#endif
