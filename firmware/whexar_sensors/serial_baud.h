// Which serial rates the board can run at: the rule whexar checks
// sensor_board.baudrate against (whexar/sensors/usart.py), as constexpr
// functions, so that the sketch refuses to build for a rate that fails it and
// the host tests check it rate by rate. C++11, no Arduino dependency.
//
// 1. The USART divides the CPU clock: f / (16 (UBRR + 1)), or f / (8 (UBRR + 1))
//    with U2X (ATmega2560 datasheet, Atmel 2549Q, 22.3.1, Table 22-1). The
//    Arduino core's Serial.begin() (HardwareSerial::begin) picks U2X with
//    UBRR = (f / 4 / baud - 1) / 2, and normal speed with
//    UBRR = (f / 8 / baud - 1) / 2 when that exceeds 4095 or, hard-coded for
//    old bootloaders, for 57600 at 16 MHz. The rate it gives must lie within
//    +-2 % of the one asked for: the datasheet's recommended receiver error
//    for 8-bit frames ("Asynchronous Operational Range", Tables 22-2, 22-3;
//    errors at 16 MHz in Table 22-12). 115200 (+2.1 %) and 57600 (+2.1 %,
//    normal speed) fail.
// 2. The rate must carry the longest frame at the highest frame rate the host
//    may set (rate=50#), 10 bits per byte, or Serial.write() blocks the loop.
#ifndef WHEXAR_SERIAL_BAUD_H
#define WHEXAR_SERIAL_BAUD_H

#include <stdint.h>

constexpr uint32_t usart_ubrr_u2x(uint32_t f, uint32_t baud) { return (f / 4 / baud - 1) / 2; }

constexpr bool usart_u2x(uint32_t f, uint32_t baud) {
    return !((f == 16000000UL && baud == 57600UL) || usart_ubrr_u2x(f, baud) > 4095);
}

constexpr uint32_t usart_ubrr(uint32_t f, uint32_t baud) {
    return usart_u2x(f, baud) ? usart_ubrr_u2x(f, baud) : (f / 8 / baud - 1) / 2;
}

// The actual rate is f / usart_divisor(f, baud).
constexpr uint32_t usart_divisor(uint32_t f, uint32_t baud) {
    return (usart_u2x(f, baud) ? 8UL : 16UL) * (usart_ubrr(f, baud) + 1);
}

constexpr uint64_t usart_absdiff(uint64_t a, uint64_t b) { return a > b ? a - b : b - a; }

// |f / d - baud| <= 2 % of baud  <=>  50 |f - baud d| <= baud d. Rates above
// f / 8 (2 Mbps at 16 MHz, UBRR = 0 with U2X) cannot be reached at all.
constexpr bool usart_within_2pct(uint32_t f, uint32_t baud) {
    return baud > 0 && baud <= f / 8 &&
           50ULL * usart_absdiff(f, (uint64_t)baud * usart_divisor(f, baud)) <=
               (uint64_t)baud * usart_divisor(f, baud);
}

// 8N1: 10 bits per byte on the wire.
constexpr bool baud_carries_frames(uint32_t baud, uint32_t frame_bytes, uint32_t frames_per_s) {
    return frame_bytes * 10UL * frames_per_s <= baud;
}

constexpr bool baud_supported(uint32_t f, uint32_t baud, uint32_t frame_bytes,
                              uint32_t frames_per_s) {
    return usart_within_2pct(f, baud) && baud_carries_frames(baud, frame_bytes, frames_per_s);
}

#endif
