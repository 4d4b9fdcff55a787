#include "frame.h"

#include "board_config.h"

#if defined(__AVR__)
#include <util/crc16.h>
#endif

uint16_t crc16_update(uint16_t crc, uint8_t byte) {
#if defined(__AVR__)
    // avr-libc's XMODEM update is the same MSB-first 0x1021 step in a few
    // instructions; XMODEM and CCITT-FALSE differ only in the initial value.
    return _crc_xmodem_update(crc, byte);
#else
    crc ^= (uint16_t)byte << 8;
    for (uint8_t i = 0; i < 8; ++i)
        crc = (uint16_t)((crc & 0x8000u) ? (crc << 1) ^ 0x1021u : crc << 1);
    return crc;
#endif
}

uint16_t crc16(const void *data, size_t len) {
    const uint8_t *p = static_cast<const uint8_t *>(data);
    uint16_t crc = CRC16_INIT;
    while (len--) crc = crc16_update(crc, *p++);
    return crc;
}

namespace {

// Appends to a bounded buffer; remembers an overflow instead of writing past it.
struct Writer {
    char *p;
    char *end;   // last usable byte is end - 1
    bool ok;

    void put(char c) {
        if (p < end) *p++ = c;
        else ok = false;
    }
    void puts(const char *s) {
        while (*s) put(*s++);
    }
    // Decimal without division: repeated subtraction costs at most
    // 5 * 9 16-bit compares on the AVR, cheaper than its software divide.
    void putu(uint16_t v) {
        static const uint16_t kPow10[] = {10000, 1000, 100, 10};
        bool lead = true;
        for (uint8_t i = 0; i < 4; ++i) {
            char d = '0';
            while (v >= kPow10[i]) {
                v = (uint16_t)(v - kPow10[i]);
                ++d;
            }
            if (d != '0' || !lead) {
                put(d);
                lead = false;
            }
        }
        put((char)('0' + v));
    }
    void puthex4(uint16_t v) {
        static const char kHex[] = "0123456789ABCDEF";
        for (int8_t shift = 12; shift >= 0; shift = (int8_t)(shift - 4))
            put(kHex[(v >> shift) & 0xF]);
    }
};

}  // namespace

size_t frame_encode(char *out, size_t cap, uint16_t seq,
                    const char *const keys[], const uint16_t values[], uint8_t n) {
    if (cap == 0) return 0;
    Writer w = {out, out + cap - 1, true};  // keep one byte for the NUL
    w.puts("seq=");
    w.putu(seq);
    w.put(';');
    for (uint8_t i = 0; i < n; ++i) {
        w.puts(keys[i]);
        w.put('=');
        w.putu(values[i]);
        w.put(';');
    }
    size_t covered = (size_t)(w.p - out);  // the CRC covers up to this ';'
    w.puts("crc=");
    w.puthex4(crc16(out, covered));
    size_t body = (size_t)(w.p - out);
    w.put('#');
    if (!w.ok || body > FRAME_MAX_BODY) {
        out[0] = '\0';
        return 0;
    }
    *w.p = '\0';
    return (size_t)(w.p - out);
}

namespace {
const char kRatePrefix[] = "rate=";
const uint8_t kPrefixLen = sizeof kRatePrefix - 1;
const uint8_t kDigits = kPrefixLen;   // prefix matched, reading digits
const uint8_t kReject = 0xFF;         // not a command: wait for '#'
const uint8_t kMaxDigits = 3;
}  // namespace

RateCommandParser::RateCommandParser() : state_(0), digits_(0), value_(0) {}

uint8_t RateCommandParser::feed(uint8_t b) {
    // Between commands (nothing matched yet) a terminal's CR/LF etc. are skipped;
    // inside a command they make it "anything else".
    if (state_ == 0 && (b == '\r' || b == '\n' || b == ' ' || b == '\t' || b == '\0')) return 0;
    if (b == '#') {
        uint8_t result = 0;
        if (state_ == kDigits && digits_ > 0 && value_ >= FRAME_RATE_MIN_HZ &&
            value_ <= FRAME_RATE_MAX_HZ)
            result = (uint8_t)value_;
        state_ = 0;
        digits_ = 0;
        value_ = 0;
        return result;
    }
    if (state_ < kPrefixLen) {
        state_ = (b == (uint8_t)kRatePrefix[state_]) ? (uint8_t)(state_ + 1) : kReject;
    } else if (state_ == kDigits) {
        if (b >= '0' && b <= '9' && digits_ < kMaxDigits) {
            value_ = (uint16_t)(value_ * 10 + (b - '0'));
            ++digits_;
        } else {
            state_ = kReject;
        }
    }
    return 0;
}
