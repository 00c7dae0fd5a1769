#include "burrow.h"

namespace mrq {

namespace {

const float DEG = 0.0174532925f;
const BurrowPoses TABLE_II[3] = {
    {{-75 * DEG, -50 * DEG}, {-40 * DEG, 30 * DEG}},   // DH
    {{-75 * DEG, -50 * DEG}, {-40 * DEG, 0 * DEG}},    // DL
    {{-40 * DEG, -20 * DEG}, {-40 * DEG, 30 * DEG}},   // SH
};

}  // namespace

const BurrowPoses* burrow_poses(uint8_t mode) {
  if (mode < BURROW_DH || mode > BURROW_SH) return 0;
  return &TABLE_II[mode - BURROW_DH];
}

}  // namespace mrq
