// Pins and compile-time defaults of the WHexaR sensor board (Arduino Mega
// 2560, ATmega2560 at 16 MHz). Plain C preprocessor, no Arduino dependency,
// so the host tests can include it too.
#ifndef WHEXAR_BOARD_CONFIG_H
#define WHEXAR_BOARD_CONFIG_H

// ADC channels. analogRead() on the Mega takes the channel number as well as
// the pin (A0 == 54 -> channel 0), and the simavr harness uses the same numbers.
#define PIN_IR1 0   // A0: IR rangefinder, right front leg (thesis 5.3.5)
#define PIN_IR2 1   // A1: IR rangefinder, left front leg
#define PIN_FSR0 2  // A2..A7: FSR of leg 0..5 (thesis 5.3.3, Fig. 4.2 numbering)
#define PIN_FSR1 3
#define PIN_FSR2 4
#define PIN_FSR3 5
#define PIN_FSR4 6
#define PIN_FSR5 7
#define PIN_ACCX 8  // A8..A10: optional analog accelerometer (WITH_ACCEL=1)
#define PIN_ACCY 9
#define PIN_ACCZ 10

// Every input is sampled at 50 Hz (thesis 6.1.2, 6.1.5).
#define SAMPLE_RATE_HZ 50
#define SAMPLE_PERIOD_US (1000000UL / SAMPLE_RATE_HZ)

// Frames per second: 20 by default (thesis 5.4); the host may change it at
// run time with `rate=N#`, N in FRAME_RATE_MIN_HZ..FRAME_RATE_MAX_HZ.
#ifndef FRAME_RATE_HZ
#define FRAME_RATE_HZ 20
#endif
#define FRAME_RATE_MIN_HZ 10
#define FRAME_RATE_MAX_HZ 50
#if FRAME_RATE_HZ < FRAME_RATE_MIN_HZ || FRAME_RATE_HZ > FRAME_RATE_MAX_HZ
#error "FRAME_RATE_HZ must be 10..50"
#endif

// 1: sample A8..A10 and send accx/accy/accz; 0 (default): omit them. The
// thesis names no analog accelerometer -- body tilt comes from the IMU on the
// Raspberry Pi (5.3.4, 5.4) -- and an unfitted one's open inputs would read as
// a bogus acceleration. whexar's sensor_board.accelerometer.fitted agrees.
#ifndef WITH_ACCEL
#define WITH_ACCEL 0
#endif

// 1 Mbps 8N1 by default (thesis 5.4). At 16 MHz the Arduino core picks U2X
// with UBRR = 1: 16 MHz / (8 * (1 + 1)) = 1 Mbps exactly (datasheet 22.3.1).
// The build option BAUD sets another rate; serial_baud.h says which pass.
#ifndef SERIAL_BAUD
#define SERIAL_BAUD 1000000UL
#endif

// The longest frame this build sends, '#' included: "seq=65535;", 4-digit
// values ("ir1=1023;" 9 bytes, "accx=1023;" and "fsr0=1023;" 10), "crc=XXXX#".
#define FRAME_LONGEST_BYTES (10 + 2 * 9 + (WITH_ACCEL ? 3 * 10 : 0) + 6 * 10 + 9)

#endif
