// The board's side of PROTOCOL.md: the checked frame encoder, CRC-16/CCITT-FALSE
// and the parser of the host's `rate=N#` command. No heap, no printf, no
// Arduino dependency: the host tests compile the same code with g++.
#ifndef WHEXAR_FRAME_H
#define WHEXAR_FRAME_H

#include <stddef.h>
#include <stdint.h>

// PROTOCOL.md "Limits": at most 192 bytes before the '#'.
#define FRAME_MAX_BODY 192
// Room for the longest frame: the body, '#' and a terminating NUL.
#define FRAME_BUF_SIZE (FRAME_MAX_BODY + 2)

// CRC-16/CCITT-FALSE: poly 0x1021, init 0xFFFF, no reflection, no final XOR
// (check value 0x29B1 for "123456789"); Python: binascii.crc_hqx(data, 0xFFFF).
#define CRC16_INIT 0xFFFFu
uint16_t crc16_update(uint16_t crc, uint8_t byte);
uint16_t crc16(const void *data, size_t len);

// Writes "seq=S;k0=v0;...;kn-1=vn-1;crc=XXXX#" and a NUL into out[0..cap).
// keys[i] are the field names in frame order, values[i] their values.
// Returns the frame's length without the NUL, or 0 if it does not fit in cap
// or its body would exceed FRAME_MAX_BODY (out then holds no valid frame).
size_t frame_encode(char *out, size_t cap, uint16_t seq,
                    const char *const keys[], const uint16_t values[], uint8_t n);

// Host -> board command `rate=N#`, fed one byte at a time.
// A command is the bytes since the previous '#' (or since start-up), less any
// leading CR, LF, space, tab or NUL (a terminal's line ends); it must be exactly
// "rate=" and 1..3 digits with N in FRAME_RATE_MIN_HZ..FRAME_RATE_MAX_HZ.
// Anything else is ignored up to the next '#', so garbage or a cut-off
// command never blocks the next one.
class RateCommandParser {
public:
    RateCommandParser();
    // Returns N when b completes a valid command, else 0.
    uint8_t feed(uint8_t b);

private:
    uint8_t state_;    // chars of "rate=" matched, or kDigits / kReject
    uint8_t digits_;
    uint16_t value_;
};

#endif
