// WHexaR sensor board: ATmega2560 on an Arduino Mega 2560 (thesis 5.3, 5.4).
// Samples the IR rangefinders, the leg FSRs and, in a WITH_ACCEL=1 build, an
// analog accelerometer at 50 Hz, filters each input with a 5-sample trimmed
// mean and sends a checked text frame (PROTOCOL.md) at 20 Hz (10..50, set by
// the host with `rate=N#`) over the USB serial line at 1 Mbps (BAUD).
#include <avr/sleep.h>

#include "board_config.h"
#include "frame.h"
#include "sensor_filter.h"
#include "serial_baud.h"

static_assert(baud_supported(F_CPU, SERIAL_BAUD, FRAME_LONGEST_BYTES, FRAME_RATE_MAX_HZ),
              "BAUD: the USART at F_CPU misses it by more than 2 % as Serial.begin() sets it, "
              "or it cannot carry the longest frame at FRAME_RATE_MAX_HZ (serial_baud.h)");

// Sampled channels and their keys, in frame order (PROTOCOL.md "Fields").
static const uint8_t kChannels[] = {
    PIN_IR1, PIN_IR2,
#if WITH_ACCEL
    PIN_ACCX, PIN_ACCY, PIN_ACCZ,
#endif
    PIN_FSR0, PIN_FSR1, PIN_FSR2, PIN_FSR3, PIN_FSR4, PIN_FSR5,
};
static const char *const kKeys[] = {
    "ir1", "ir2",
#if WITH_ACCEL
    "accx", "accy", "accz",
#endif
    "fsr0", "fsr1", "fsr2", "fsr3", "fsr4", "fsr5",
};
static const uint8_t kInputs = sizeof kChannels;
static_assert(sizeof kKeys / sizeof kKeys[0] == sizeof kChannels, "one key per channel");

static TrimmedMean5 filters[kInputs];
static RateCommandParser rate_parser;
static char frame_buf[FRAME_BUF_SIZE];
static uint16_t seq;  // 0 after reset, wraps at 65535

// Absolute deadlines in micros(); advanced by whole periods (next += period)
// so the schedule does not drift with the loop's latency.
static uint32_t next_sample_us;
static uint32_t next_frame_us;
// Frame period 1e6/N us split into quotient and remainder; the remainder is
// accumulated so that N frames take exactly one second even when N does not
// divide 1e6 (e.g. 30 Hz).
static uint8_t frame_rate_hz;
static uint32_t frame_period_us;
static uint8_t frame_period_rem;
static uint8_t frame_rem_acc;

static bool reached(uint32_t now, uint32_t deadline) {
    return (int32_t)(now - deadline) >= 0;  // wrap-safe (micros() wraps every 71 min)
}

static void set_frame_rate(uint8_t hz) {
    frame_rate_hz = hz;
    frame_period_us = 1000000UL / hz;
    frame_period_rem = (uint8_t)(1000000UL % hz);
    frame_rem_acc = 0;
}

static void sample_all() {
    for (uint8_t i = 0; i < kInputs; ++i) filters[i].push((uint16_t)analogRead(kChannels[i]));
}

static void send_frame() {
    uint16_t values[kInputs];
    for (uint8_t i = 0; i < kInputs; ++i) values[i] = filters[i].value();
    size_t len = frame_encode(frame_buf, sizeof frame_buf, seq, kKeys, values, kInputs);
    Serial.write(reinterpret_cast<const uint8_t *>(frame_buf), len);
    ++seq;
}

// The Arduino core starts timers 1..5 for analogWrite() PWM; this board has no
// PWM outputs, so stop them (timer0 keeps millis()/micros()). It also keeps
// simavr fast: simavr 1.6 does not model the core's phase-correct PWM mode
// and would otherwise service those timers every few dozen cycles.
static void stop_unused_timers() {
    TCCR1B = 0;
    TCCR2B = 0;
    TCCR3B = 0;
    TCCR4B = 0;
    TCCR5B = 0;
}

void setup() {
    stop_unused_timers();
    Serial.begin(SERIAL_BAUD);
    set_frame_rate(FRAME_RATE_HZ);
    sample_all();  // fills every window, so the first frame is a valid reading
    uint32_t now = micros();
    next_sample_us = now + SAMPLE_PERIOD_US;
    next_frame_us = now + frame_period_us;  // first frame one period after start-up
    // Idle sleep stops the CPU but keeps timer0 and the UART running; timer0's
    // overflow (every 1.024 ms) wakes the loop. It also lets simavr skip ahead.
    set_sleep_mode(SLEEP_MODE_IDLE);
}

void loop() {
    uint32_t now = micros();

    // Sample before sending, so a frame due at the same time has the newest sample.
    if (reached(now, next_sample_us)) {
        sample_all();
        next_sample_us += SAMPLE_PERIOD_US;
        // A whole period behind (cannot happen in normal operation): skip the
        // missed slots rather than sampling in a burst.
        if (reached(now, next_sample_us)) next_sample_us = now + SAMPLE_PERIOD_US;
    }

    if (reached(now, next_frame_us)) {
        send_frame();
        next_frame_us += frame_period_us;
        frame_rem_acc = (uint8_t)(frame_rem_acc + frame_period_rem);
        if (frame_rem_acc >= frame_rate_hz) {
            frame_rem_acc = (uint8_t)(frame_rem_acc - frame_rate_hz);
            ++next_frame_us;
        }
        if (reached(now, next_frame_us)) next_frame_us = now + frame_period_us;
    }

    // A new rate applies from the next frame on: the frame already scheduled
    // keeps its time, the intervals after it use the new period.
    while (Serial.available() > 0) {
        uint8_t hz = rate_parser.feed((uint8_t)Serial.read());
        if (hz) set_frame_rate(hz);
    }

    sleep_mode();
}
