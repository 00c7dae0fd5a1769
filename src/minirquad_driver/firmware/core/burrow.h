// Burrowing poses of the paper's Table II (Huh et al., RA-L 2023, section VI-B): each mode
// moves the proximal legs to theta_L1 and the distal legs to theta_L2, first to the
// retracting pose, then to the final pose. UNBURROW returns the legs to 0.
#ifndef MRQ_BURROW_H
#define MRQ_BURROW_H

#include <stdint.h>

#include "messages.h"

namespace mrq {

struct BurrowPoses {
  float retract[2];   // rad: theta_L1 (proximal), theta_L2 (distal)
  float final_[2];
};

// Poses of mode DH, DL or SH (BurrowMode 1..3); null for any other value.
const BurrowPoses* burrow_poses(uint8_t mode);

// The four leg targets of a (proximal, distal) pose, in leg order.
inline void pose_targets(const float pose[2], float target[4]) {
  target[0] = target[1] = pose[0];
  target[2] = target[3] = pose[1];
}

}  // namespace mrq

#endif
