// The firmware core's behaviour on a fake board: acks and retries, watchdogs, e-stop,
// winch rules, INA219 resets, burrow sequencing, the gait clock, the clock wrap.
#include <math.h>
#include <string.h>

#include <vector>

#include "../core/burrow.h"
#include "../core/firmware.h"
#include "../core/gait_clock.h"
#include "check.h"
#include "fake_hal.h"

namespace {

using mrq::Frame;
using mrq::Message;

struct Rig {
  fake::Board board;
  mrq::Config config;
  mrq::Firmware fw;
  std::vector<Frame> out;
  uint8_t host_seq;
  std::vector<uint8_t> sent[256];   // the last frame sent with each seq, for retries
  explicit Rig(uint32_t start_ms = 0, mrq::Config c = mrq::default_config())
      : config(c), fw(board.hal(), config), host_seq(0) {
    board.clock.ms = start_ms;
    for (int i = 0; i < 4; ++i) board.servos.pos[i] = config.legs[i].zero;   // legs at 0
    fw.begin(mrq::RESET_POWER_ON);
    collect();
    run(20);   // a first load-cell reading: the tension is known
  }
  void collect() {
    std::vector<Frame> f = fake::drain(board.serial);
    out.insert(out.end(), f.begin(), f.end());
  }
  // Advance the clock ms by ms, the firmware and the servos with it.
  void run(uint32_t ms, bool heartbeats = true) {
    for (uint32_t i = 0; i < ms; ++i) {
      ++board.clock.ms;
      if (heartbeats && board.clock.ms % 100 == 0) send(heartbeat());
      fw.loop();
      board.servos.step(1e-3);
    }
    collect();
  }
  // A new frame, stamped with the clock in ms as the host stamps its own.
  uint8_t send(const Message& m, int seq = -1) {
    const uint8_t s = seq < 0 ? host_seq++ : uint8_t(seq);
    sent[s] = fake::wire(m, s, board.clock.ms);
    board.serial.feed(sent[s]);
    return s;
  }
  void send_now(const Message& m, int seq = -1) {
    send(m, seq);
    fw.loop();
    collect();
  }
  // The host's retry: the same bytes as the frame first sent with this seq.
  void resend_now(uint8_t seq) {
    board.serial.feed(sent[seq]);
    fw.loop();
    collect();
  }
  std::vector<Frame> of(uint8_t type) const {
    std::vector<Frame> r;
    for (size_t i = 0; i < out.size(); ++i) {
      if (out[i].message.type == type) r.push_back(out[i]);
    }
    return r;
  }
  const Frame* last(uint8_t type) const {
    for (size_t i = out.size(); i-- > 0;) {
      if (out[i].message.type == type) return &out[i];
    }
    return 0;
  }
  float angle(int leg) const {
    return mrq::leg_angle(config.legs[leg], int32_t(floor(board.servos.pos[leg])));
  }
  static Message heartbeat() {
    Message m;
    m.type = mrq::MSG_HEARTBEAT;
    return m;
  }
};

Message winch(int32_t speed, uint16_t hold_ms = 0) {
  Message m;
  m.type = mrq::MSG_WINCH;
  m.winch.speed = speed;
  m.winch.hold_ms = hold_ms;
  return m;
}
Message estop(bool on) {
  Message m;
  m.type = mrq::MSG_ESTOP;
  m.estop.engage = on ? 1 : 0;
  return m;
}
Message burrow(uint8_t mode) {
  Message m;
  m.type = mrq::MSG_BURROW;
  m.burrow.mode = mode;
  return m;
}
Message walk() {
  Message m;
  m.type = mrq::MSG_SET_GAIT;
  mrq::SetGait& g = m.set_gait;
  g.kind = mrq::GAIT_CLOCK;
  g.period_ms = 2000;
  g.duty = 4200;
  g.sweep = 698132;   // 40 deg
  g.down = -349066;   // -20 deg: MiniRHex's stance centre, toe back
  g.phase[0] = 0;
  g.phase[1] = g.phase[2] = 32768;
  g.phase[3] = 0;
  g.direction = 1;
  return m;
}

bool has_error(const Rig& r, uint8_t code) {
  std::vector<Frame> e = r.of(mrq::MSG_ERROR);
  for (size_t i = 0; i < e.size(); ++i) {
    if (e[i].message.error.code == code) return true;
  }
  return false;
}

}  // namespace

TEST(reset_notice_comes_first) {
  Rig r;
  CHECK(!r.out.empty());
  CHECK_EQ(r.out[0].message.type, mrq::MSG_RESET_NOTICE);
  CHECK_EQ(r.out[0].seq, 0);
  CHECK_EQ(r.out[0].message.about.reset_cause, mrq::RESET_POWER_ON);
  CHECK_EQ(r.out[0].message.about.telemetry_hz, 100);
  r.run(1000);
  // 100 Hz telemetry, 50 Hz power, every frame numbered in order.
  std::vector<Frame> t = r.of(mrq::MSG_TELEMETRY), p = r.of(mrq::MSG_POWER);
  CHECK_NEAR(double(t.size()), 102.0, 1.0);   // 1.02 s since boot
  CHECK_NEAR(double(p.size()), 51.0, 1.0);
  for (size_t i = 2; i < t.size(); ++i) CHECK_EQ(t[i].t_ms - t[i - 1].t_ms, 10u);
  for (size_t i = 1; i < r.out.size(); ++i) CHECK_EQ(r.out[i].seq, uint8_t(r.out[i - 1].seq + 1));
}

TEST(commands_are_acked_and_retries_not_executed_twice) {
  Rig r;
  r.run(20);
  const uint8_t s = r.send(burrow(mrq::BURROW_SH));
  r.run(30);
  const Frame* ack = r.last(mrq::MSG_ACK);
  CHECK(ack && ack->message.ack.acked_seq == s && ack->message.ack.result == mrq::ACK_OK);
  CHECK_EQ(r.fw.mode(), mrq::MODE_BURROW_RETRACT);
  r.run(4000);
  CHECK_EQ(r.fw.mode(), mrq::MODE_ANCHORED);
  r.out.clear();
  r.resend_now(s);                             // the host's retry: the same frame
  ack = r.last(mrq::MSG_ACK);
  CHECK(ack && ack->message.ack.acked_seq == s && ack->message.ack.result == mrq::ACK_OK);
  CHECK_EQ(r.fw.mode(), mrq::MODE_ANCHORED);   // not restarted
  r.send_now(burrow(mrq::BURROW_SH));          // a new seq: executed
  CHECK_EQ(r.fw.mode(), mrq::MODE_BURROW_RETRACT);
}

// Burrow SH and run until anchored; the BURROW's seq.
static uint8_t anchored_by_sh(Rig& r) {
  const uint8_t s = r.send(burrow(mrq::BURROW_SH));
  r.run(4000);
  CHECK_EQ(r.fw.mode(), mrq::MODE_ANCHORED);
  return s;
}

TEST(a_retry_after_a_command_of_another_channel_is_not_executed_twice) {
  // The BURROW's ack was lost and a WINCH went out before the host's retry: the retry is
  // still recognised (each channel remembers its last command), so the legs do not start
  // the burrow over from its retracting pose.
  Rig r;
  const uint8_t s = anchored_by_sh(r);
  r.send_now(winch(0));
  r.resend_now(s);
  const Frame* ack = r.last(mrq::MSG_ACK);
  CHECK(ack && ack->message.ack.acked_seq == s && ack->message.ack.acked_type == mrq::MSG_BURROW);
  CHECK_EQ(r.fw.mode(), mrq::MODE_ANCHORED);
}

TEST(a_new_command_with_its_channels_last_seq_is_executed) {
  // 256 host frames later the seq counter comes round: the same seq and type, a new stamp.
  Rig r;
  const uint8_t s = anchored_by_sh(r);
  r.send_now(burrow(mrq::BURROW_SH), s);
  CHECK_EQ(r.fw.mode(), mrq::MODE_BURROW_RETRACT);
}

TEST(a_retry_of_a_refused_command_gets_the_same_answer) {
  Rig r;
  r.send_now(estop(true));
  const uint8_t s = r.send(winch(20000));
  r.run(5);
  CHECK_EQ(r.last(mrq::MSG_ACK)->message.ack.result, mrq::ACK_ESTOPPED);
  r.resend_now(s);
  CHECK_EQ(r.last(mrq::MSG_ACK)->message.ack.result, mrq::ACK_ESTOPPED);
  CHECK_EQ(r.fw.winch().speed_command(), 0);
}

TEST(estop_holds_legs_brakes_winch_and_refuses_motion) {
  Rig r;
  r.send_now(walk());
  for (int i = 0; i < 6; ++i) {   // the winch command refreshed, as behavior_node does
    r.send_now(winch(20000));
    r.run(50);
  }
  CHECK(r.board.winch.duty > 0);
  CHECK_EQ(r.fw.mode(), mrq::MODE_WALKING);
  r.send_now(estop(true));
  r.run(200);
  CHECK_EQ(r.fw.reported_mode(), mrq::MODE_ESTOPPED);
  CHECK_EQ(r.board.winch.duty, 0);
  CHECK(r.board.winch.brake);
  for (int i = 0; i < 4; ++i) CHECK(abs(r.board.servos.goal[i]) <= 1);   // holding
  r.send_now(walk());
  CHECK_EQ(r.last(mrq::MSG_ACK)->message.ack.result, mrq::ACK_ESTOPPED);
  const Frame* tel = r.last(mrq::MSG_TELEMETRY);
  CHECK(tel && (tel->message.telemetry.flags & mrq::FLAG_ESTOP));
  r.send_now(estop(false));
  r.run(50);
  CHECK_EQ(r.fw.reported_mode(), mrq::MODE_IDLE);   // released, motion does not restart
  CHECK_EQ(r.board.winch.duty, 0);
}

TEST(host_watchdog_stops_legs_and_winch_once_and_heartbeat_clears_flag) {
  Rig r;
  r.send_now(walk());
  r.send_now(winch(20000));
  // The host falls silent (no heartbeats, no winch refresh) after its last frame, now.
  const uint32_t t0 = r.board.clock.ms;
  bool moving = true;
  while (r.board.clock.ms - t0 < 1500) {
    r.run(1, false);
    if (r.fw.watchdog_tripped() && moving) {
      moving = false;
      CHECK(r.board.clock.ms - t0 > 500 && r.board.clock.ms - t0 <= 511);   // + one cycle
    }
  }
  CHECK(r.fw.watchdog_tripped());
  CHECK_EQ(r.fw.reported_mode(), mrq::MODE_WATCHDOG);
  CHECK_EQ(r.board.winch.duty, 0);
  for (int i = 0; i < 4; ++i) CHECK(abs(r.board.servos.goal[i]) <= 1);
  int watchdog_errors = 0;
  std::vector<Frame> e = r.of(mrq::MSG_ERROR);
  for (size_t i = 0; i < e.size(); ++i) {
    watchdog_errors += e[i].message.error.code == mrq::ERR_HOST_WATCHDOG ? 1 : 0;
  }
  CHECK_EQ(watchdog_errors, 1);
  r.send_now(Rig::heartbeat());
  CHECK(!r.fw.watchdog_tripped());
  r.run(100);
  CHECK_EQ(r.fw.mode(), mrq::MODE_IDLE);   // the gait does not restart by itself
}

TEST(winch_deadman_is_not_fed_by_heartbeats) {
  Rig r;
  r.send_now(winch(20000));
  r.run(60);
  CHECK(r.board.winch.duty > 0);
  r.run(60);   // heartbeats keep coming, the winch command does not
  CHECK_EQ(r.board.winch.duty, 0);
  CHECK(has_error(r, mrq::ERR_WINCH_DEADMAN));
  const Frame* e = r.last(mrq::MSG_ERROR);
  CHECK(e && e->message.error.detail > 80 && e->message.error.detail <= 91);
  CHECK(!r.fw.watchdog_tripped());
}

TEST(a_winch_command_runs_no_longer_than_its_hold) {
  // A command whose evidence has 30 ms left: the winch stands after 30 ms (one 10 ms control
  // cycle later at most), not after the 80 ms deadman; a refresh starts a new hold, and a hold
  // above the deadman is cut to the deadman.
  Rig r;
  r.send_now(winch(20000, 30));
  r.run(20);
  CHECK(r.board.winch.duty > 0);
  r.run(30);
  CHECK_EQ(r.board.winch.duty, 0);
  const Frame* e = r.last(mrq::MSG_ERROR);
  CHECK(e && e->message.error.code == mrq::ERR_WINCH_DEADMAN);
  CHECK(e && e->message.error.detail > 30 && e->message.error.detail <= 41);
  r.send_now(winch(0));
  r.send_now(winch(20000, 30));
  r.run(20);
  r.send_now(winch(20000, 30));
  r.run(20);
  CHECK(r.board.winch.duty > 0);      // 40 ms after the first command, 20 after the refresh
  r.send_now(winch(20000, 5000));
  r.run(120);
  CHECK_EQ(r.board.winch.duty, 0);
  e = r.last(mrq::MSG_ERROR);
  CHECK(e && e->message.error.detail > 80 && e->message.error.detail <= 91);
}

TEST(overtension_brakes_and_latches_until_the_host_stops) {
  Rig r;
  r.send_now(winch(20000));
  r.run(20);
  r.board.winch.load = 8400 + int32_t(13.0 / 0.0046762e-3);   // 13 N > 12 N
  for (int i = 0; i < 10; ++i) {
    r.send_now(winch(20000));
    r.run(10);
  }
  CHECK(has_error(r, mrq::ERR_WINCH_OVERTENSION));
  CHECK_EQ(r.board.winch.duty, 0);
  CHECK_EQ(r.last(mrq::MSG_ACK)->message.ack.result, mrq::ACK_BUSY);
  r.board.winch.load = 8400;
  r.send_now(winch(20000));
  CHECK_EQ(r.last(mrq::MSG_ACK)->message.ack.result, mrq::ACK_BUSY);   // still latched
  r.send_now(winch(0));
  r.send_now(winch(20000));
  CHECK_EQ(r.last(mrq::MSG_ACK)->message.ack.result, mrq::ACK_OK);
  r.run(10);
  CHECK(r.board.winch.duty > 0);
}

TEST(stall_brakes_flags_and_latches) {
  Rig r;
  for (int i = 0; i < 60; ++i) {   // the encoder never moves: a jammed spool
    r.send_now(winch(30000));
    r.run(10);
  }
  CHECK(has_error(r, mrq::ERR_WINCH_STALL));
  CHECK_EQ(r.board.winch.duty, 0);
  const Frame* tel = r.last(mrq::MSG_TELEMETRY);
  CHECK(tel && (tel->message.telemetry.flags & mrq::FLAG_WINCH_STALLED));
  CHECK_EQ(r.last(mrq::MSG_ACK)->message.ack.result, mrq::ACK_BUSY);
}

TEST(load_cell_loss_refuses_reel_in_but_allows_pay_out) {
  Rig r;
  r.send_now(winch(20000));
  r.run(20);
  r.board.winch.load_ready = false;
  for (int i = 0; i < 8; ++i) {
    r.send_now(winch(20000));
    r.run(10);
  }
  CHECK(has_error(r, mrq::ERR_WINCH_SENSOR));
  CHECK_EQ(r.board.winch.duty, 0);
  CHECK_EQ(r.last(mrq::MSG_ACK)->message.ack.result, mrq::ACK_BUSY);
  const Frame* tel = r.last(mrq::MSG_TELEMETRY);
  CHECK(tel && (tel->message.telemetry.flags & mrq::FLAG_TENSION_INVALID));
  r.send_now(winch(-20000));
  CHECK_EQ(r.last(mrq::MSG_ACK)->message.ack.result, mrq::ACK_OK);
  r.run(10);
  CHECK(r.board.winch.duty < 0);
  r.board.winch.load_ready = true;   // the reading returns: the flag clears
  r.send_now(winch(0));
  r.run(20);
  tel = r.last(mrq::MSG_TELEMETRY);
  CHECK(tel && !(tel->message.telemetry.flags & mrq::FLAG_TENSION_INVALID));
}

TEST(ina219_reset_is_reported_as_read_then_restored) {
  Rig r;
  CHECK_EQ(r.board.ina.reg[5], 4096);        // begin() wrote the calibration
  CHECK_EQ(r.board.ina.reg[0], 0x39E7);
  r.run(30);
  CHECK_EQ(r.last(mrq::MSG_POWER)->message.power.cal, 4096);
  r.board.ina.reg[5] = 0;                    // a brown-out resets the chip
  r.board.ina.reg[0] = 0x399F;
  r.run(20);
  std::vector<Frame> p = r.of(mrq::MSG_POWER);
  int zeros = 0;
  for (size_t i = 0; i < p.size(); ++i) zeros += p[i].message.power.cal == 0 ? 1 : 0;
  CHECK_EQ(zeros, 1);                        // exactly one sample shows the reset
  r.run(40);
  CHECK_EQ(r.last(mrq::MSG_POWER)->message.power.cal, 4096);
  CHECK_EQ(r.board.ina.reg[0], 0x39E7);
  r.board.ina.ok = false;                    // a dead bus: no POWER frames, no crash
  const size_t before = r.of(mrq::MSG_POWER).size();
  r.run(100);
  CHECK_EQ(r.of(mrq::MSG_POWER).size(), before);
}

TEST(burrow_reaches_table_ii_final_pose) {
  for (uint8_t mode = mrq::BURROW_DH; mode <= mrq::BURROW_SH; ++mode) {
    Rig r;
    r.send_now(burrow(mode));
    bool saw_final = false;
    for (int k = 0; k < 800 && r.fw.mode() != mrq::MODE_ANCHORED; ++k) {
      r.run(10);
      saw_final = saw_final || r.fw.mode() == mrq::MODE_BURROW_FINAL;
    }
    CHECK(saw_final);
    CHECK_EQ(r.fw.mode(), mrq::MODE_ANCHORED);
    const mrq::BurrowPoses* p = mrq::burrow_poses(mode);
    for (int i = 0; i < 4; ++i) CHECK_NEAR(r.angle(i), p->final_[i < 2 ? 0 : 1], 0.0088);
  }
}

TEST(buehler_clock_matches_minirhex_walk) {
  // MiniRHex walk: 2 s, duty 0.42, sweep 40 deg, down 20 deg toe back (-20 deg in the
  // protocol's sign): walking forward, the slow arc 0 -> -40 deg (toe back) in 0.84 s, then
  // 320 deg of recovery on the same way round in 1.16 s (the Python reference, sim/gait.py).
  const Message m = walk();
  const float deg = 0.0174532925f;
  CHECK_NEAR(mrq::buehler_clock(m.set_gait, 0, 0).angle, 0.0, 1e-4);
  CHECK_NEAR(mrq::buehler_clock(m.set_gait, 0, 420).angle, -20 * deg, 1e-4);
  CHECK_NEAR(mrq::buehler_clock(m.set_gait, 0, 840).angle, -40 * deg, 1e-4);
  CHECK_NEAR(mrq::buehler_clock(m.set_gait, 0, 1420).angle,
             -(40 + 160) * deg + 2 * 3.14159265, 1e-3);
  CHECK_NEAR(mrq::buehler_clock(m.set_gait, 0, 100).rate, -40 * deg / 0.84, 1e-4);
  CHECK_NEAR(mrq::buehler_clock(m.set_gait, 0, 1000).rate, -320 * deg / 1.16, 1e-4);
  // Phase 0.5 at t is phase 0 at t + 1 s; any number of cycles later, the same.
  CHECK_NEAR(mrq::buehler_clock(m.set_gait, 1, 300).angle,
             mrq::buehler_clock(m.set_gait, 0, 1300).angle, 1e-4);
  CHECK_NEAR(mrq::buehler_clock(m.set_gait, 0, 4000000000u + 300).angle,
             mrq::buehler_clock(m.set_gait, 0, 300).angle, 1e-4);
}

TEST(walking_legs_follow_the_clock) {
  Rig r;
  r.send_now(walk());   // the gait clock starts now
  r.run(5003);
  // After settling, each leg is within 1 degree of its clock angle at the last control
  // cycle, 5000 ms into the gait (the goal computed there is held for 3 ms).
  const Message g = walk();
  for (int i = 0; i < 4; ++i) {
    const float want = mrq::buehler_clock(g.set_gait, i, 5000).angle;
    CHECK_NEAR(mrq::wrap_angle(r.angle(i) - want), 0.0, 0.0175);
  }
}

TEST(leg_counts_unmirror_and_wrap) {
  const mrq::LegMount left = {1024, 1}, right = {3000, -1};
  CHECK_EQ(mrq::leg_counts(left, 1024), 0);
  CHECK_EQ(mrq::leg_counts(left, 1024 + 4096 * 1000 + 5), 5);    // multi-turn
  CHECK_EQ(mrq::leg_counts(left, 1024 - 4096 * 3 - 5), -5);
  CHECK_EQ(mrq::leg_counts(left, 1024 + 2048), 2048);            // pi, not -pi
  CHECK_EQ(mrq::leg_counts(right, 3000 - 100), 100);             // mirrored
  CHECK_EQ(mrq::leg_counts(left, 2147483647), mrq::leg_counts(left, 2147483647 - 4096));
  CHECK_EQ(mrq::leg_angle_urad(left, 1024 + 2048), 3141593);
  CHECK_EQ(mrq::leg_angle_urad(left, 1024 - 2047), -3140059);
  CHECK_EQ(mrq::goal_velocity(right, 1.0f, 1620), -42);          // 1 rad/s, mirrored
  CHECK_EQ(mrq::goal_velocity(left, 100.0f, 1620), 1620);        // clamped
}

TEST(clock_wrap_changes_nothing) {
  Rig r(0xFFFFFFFFu - 700);
  r.send_now(walk());
  r.out.clear();
  r.run(1500);   // across the uint32 wrap, heartbeats flowing
  CHECK(!r.fw.watchdog_tripped());
  CHECK_EQ(r.fw.mode(), mrq::MODE_WALKING);
  CHECK_NEAR(double(r.of(mrq::MSG_TELEMETRY).size()), 150.0, 2.0);
  std::vector<Frame> t = r.of(mrq::MSG_TELEMETRY);
  for (size_t i = 1; i < t.size(); ++i) CHECK_EQ(uint32_t(t[i].t_ms - t[i - 1].t_ms), 10u);
}

TEST(tx_full_drops_frames_but_keeps_numbering) {
  Rig r;
  r.run(100);
  const uint8_t seq = r.fw.next_seq();
  r.board.serial.space = 0;
  r.run(100);
  CHECK(r.fw.tx_dropped() >= 10);
  r.board.serial.space = 1 << 20;
  r.run(20);
  const Frame* t = r.last(mrq::MSG_TELEMETRY);
  CHECK(t && uint8_t(t->seq - seq) > 10);   // the host will count the gap
}

TEST(no_telemetry_from_stale_sensors) {
  Rig r;
  r.run(50);
  const size_t n = r.of(mrq::MSG_TELEMETRY).size();
  r.board.imu.ok = false;
  r.run(100);
  CHECK_EQ(r.of(mrq::MSG_TELEMETRY).size(), n);
  r.board.imu.ok = true;
  r.board.servos.ok = false;
  const int writes = r.board.servos.writes;
  r.run(100);
  CHECK_EQ(r.of(mrq::MSG_TELEMETRY).size(), n);
  CHECK_EQ(r.board.servos.writes, writes);   // no goal from stale angles
  CHECK(r.fw.servo_read_errors() >= 10);   // one per 10 ms control cycle
}

TEST(mcu_types_sent_to_the_mcu_are_not_acked) {
  Rig r;
  Message m;
  m.type = mrq::MSG_POWER;
  memset(&m.power, 0, sizeof(m.power));
  r.out.clear();
  r.send_now(m);
  CHECK(r.of(mrq::MSG_ACK).empty());
  CHECK_EQ(r.fw.wrong_direction(), 1);
}
