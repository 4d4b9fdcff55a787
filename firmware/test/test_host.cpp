// Host unit tests of the firmware's portable parts: the trimmed-mean filter,
// the frame encoder with its CRC, the `rate=N#` parser (PROTOCOL.md), and the
// serial-rate rule of serial_baud.h.
#include <stdio.h>
#include <string.h>

#include "board_config.h"
#include "frame.h"
#include "sensor_filter.h"
#include "serial_baud.h"

static int failures;
static int checks;

#define CHECK(cond)                                                        \
    do {                                                                   \
        ++checks;                                                          \
        if (!(cond)) {                                                     \
            ++failures;                                                    \
            fprintf(stderr, "%s:%d: CHECK(%s) failed\n", __FILE__, __LINE__, #cond); \
        }                                                                  \
    } while (0)

#define CHECK_EQ(a, b)                                                     \
    do {                                                                   \
        ++checks;                                                          \
        long long a_ = (long long)(a), b_ = (long long)(b);                \
        if (a_ != b_) {                                                    \
            ++failures;                                                    \
            fprintf(stderr, "%s:%d: %s == %lld, expected %s == %lld\n", __FILE__, __LINE__, \
                    #a, a_, #b, b_);                                       \
        }                                                                  \
    } while (0)

#define CHECK_STR(a, b)                                                    \
    do {                                                                   \
        ++checks;                                                          \
        if (strcmp((a), (b)) != 0) {                                       \
            ++failures;                                                    \
            fprintf(stderr, "%s:%d: got\n  %s\nexpected\n  %s\n", __FILE__, __LINE__, (a), (b)); \
        }                                                                  \
    } while (0)

static unsigned round3(unsigned s) { return (s + 1) / 3; }

// ------------------------------------------------------------ filter

static void test_filter_start_and_constant() {
    TrimmedMean5 f;
    CHECK_EQ(f.value(), 0);
    f.push(402);  // the first sample fills the window
    CHECK_EQ(f.value(), 402);
    for (int i = 0; i < 20; ++i) {
        f.push(402);
        CHECK_EQ(f.value(), 402);
    }
    TrimmedMean5 lo, hi;
    lo.push(0);
    hi.push(1023);
    for (int i = 0; i < 7; ++i) {
        lo.push(0);
        hi.push(1023);
    }
    CHECK_EQ(lo.value(), 0);
    CHECK_EQ(hi.value(), 1023);
}

static void test_filter_spike_never_shows() {
    TrimmedMean5 f;
    f.push(100);
    f.push(1023);  // one-sample spike up
    for (int i = 0; i < 6; ++i) {
        CHECK_EQ(f.value(), 100);
        f.push(100);
    }
    f.push(0);     // and down
    for (int i = 0; i < 6; ++i) {
        CHECK_EQ(f.value(), 100);
        f.push(100);
    }
}

// PROTOCOL.md "Timing": a for one more sample, round((2a+b)/3), round((a+2b)/3),
// then b from the fourth new sample on.
static void check_step(unsigned a, unsigned b) {
    TrimmedMean5 f;
    f.push((uint16_t)a);
    f.push((uint16_t)a);
    f.push((uint16_t)b);
    CHECK_EQ(f.value(), a);
    f.push((uint16_t)b);
    CHECK_EQ(f.value(), round3(2 * a + b));
    f.push((uint16_t)b);
    CHECK_EQ(f.value(), round3(a + 2 * b));
    f.push((uint16_t)b);
    CHECK_EQ(f.value(), b);
    f.push((uint16_t)b);
    CHECK_EQ(f.value(), b);
}

static void test_filter_steps() {
    check_step(100, 200);
    check_step(200, 100);
    check_step(0, 1023);
    check_step(1023, 0);
    check_step(10, 11);   // rounding: (20 + 11 + 1) / 3 = 10, (10 + 22 + 1) / 3 = 11
    check_step(0, 1);     // (0 + 0 + 1 + 1) / 3 = 0, (0 + 2 + 1) / 3 = 1
}

static void test_filter_trimmed_mean_rounding() {
    TrimmedMean5 f;
    const uint16_t w[] = {7, 1, 5, 6, 1000};  // drop 1 and 1000: (7+5+6+1)/3 = 6
    f.push(w[0]);
    for (int i = 1; i < 5; ++i) f.push(w[i]);
    CHECK_EQ(f.value(), 6);
    f.push(2);  // window 1 5 6 1000 2 -> middle 2 5 6 = 13 -> (13+1)/3 = 4
    CHECK_EQ(f.value(), 4);
    f.push(3);  // window 5 6 1000 2 3 -> middle 3 5 6 = 14 -> 5
    CHECK_EQ(f.value(), 5);
}

// ------------------------------------------------------------ CRC and frames

static void test_crc() {
    CHECK_EQ(crc16("123456789", 9), 0x29B1);  // CRC-16/CCITT-FALSE check value
    CHECK_EQ(crc16("", 0), 0xFFFF);
    uint16_t c = CRC16_INIT;
    for (const char *p = "123456789"; *p; ++p) c = crc16_update(c, (uint8_t)*p);
    CHECK_EQ(c, 0x29B1);
    // PROTOCOL.md's example frame (binascii.crc_hqx(..., 0xFFFF) == 0x7A49).
    const char *ex = "seq=4711;ir1=402;ir2=118;accx=338;accy=337;accz=405;fsr0=0;fsr1=12;"
                     "fsr2=230;fsr3=251;fsr4=0;fsr5=198;";
    CHECK_EQ(crc16(ex, strlen(ex)), 0x7A49);
}

static const char *const kAllKeys[] = {"ir1", "ir2", "accx", "accy", "accz", "fsr0",
                                       "fsr1", "fsr2", "fsr3", "fsr4", "fsr5"};

static void test_frame_example() {
    const uint16_t v[] = {402, 118, 338, 337, 405, 0, 12, 230, 251, 0, 198};
    char buf[FRAME_BUF_SIZE];
    size_t n = frame_encode(buf, sizeof buf, 4711, kAllKeys, v, 11);
    const char *want = "seq=4711;ir1=402;ir2=118;accx=338;accy=337;accz=405;fsr0=0;fsr1=12;"
                       "fsr2=230;fsr3=251;fsr4=0;fsr5=198;crc=7A49#";
    CHECK_STR(buf, want);
    CHECK_EQ(n, strlen(want));
}

static void test_frame_without_accel_and_extremes() {
    static const char *const keys[] = {"ir1", "ir2", "fsr0", "fsr1", "fsr2", "fsr3", "fsr4", "fsr5"};
    const uint16_t v[] = {0, 1023, 1, 10, 99, 100, 999, 1000};
    char buf[FRAME_BUF_SIZE];
    size_t n = frame_encode(buf, sizeof buf, 0, keys, v, 8);
    const char *body = "seq=0;ir1=0;ir2=1023;fsr0=1;fsr1=10;fsr2=99;fsr3=100;fsr4=999;fsr5=1000;";
    char want[FRAME_BUF_SIZE];
    snprintf(want, sizeof want, "%scrc=%04X#", body, crc16(body, strlen(body)));
    CHECK_STR(buf, want);
    CHECK_EQ(n, strlen(want));

    uint16_t big[] = {65535};
    static const char *const k1[] = {"x"};
    n = frame_encode(buf, sizeof buf, 65535, k1, big, 1);
    body = "seq=65535;x=65535;";
    snprintf(want, sizeof want, "%scrc=%04X#", body, crc16(body, strlen(body)));
    CHECK_STR(buf, want);
}

static void test_frame_bounds() {
    const uint16_t v[] = {1023, 1023, 1023, 1023, 1023, 1023, 1023, 1023, 1023, 1023, 1023};
    char buf[FRAME_BUF_SIZE];
    size_t full = frame_encode(buf, sizeof buf, 65535, kAllKeys, v, 11);
    CHECK(full > 0);
    CHECK(full - 1 <= FRAME_MAX_BODY);  // the longest real frame is well within the limit
    // Exactly enough room (frame + NUL) works; one byte less fails cleanly.
    char small[FRAME_BUF_SIZE];
    memset(small, 'Z', sizeof small);
    CHECK_EQ(frame_encode(small, full + 1, 65535, kAllKeys, v, 11), full);
    CHECK_STR(small, buf);
    memset(small, 'Z', sizeof small);
    CHECK_EQ(frame_encode(small, full, 65535, kAllKeys, v, 11), 0);
    CHECK_EQ(small[full], 'Z');  // nothing written past cap
    CHECK_EQ(small[0], '\0');
    CHECK_EQ(frame_encode(small, 0, 0, kAllKeys, v, 11), 0);
    // A body over 192 bytes is refused even if the buffer is larger.
    static const char *const keys40[] = {
        "abcdefghijklmnopqrst", "abcdefghijklmnopqrst", "abcdefghijklmnopqrst",
        "abcdefghijklmnopqrst", "abcdefghijklmnopqrst", "abcdefghijklmnopqrst",
        "abcdefghijklmnopqrst", "abcdefghijklmnopqrst"};
    char huge[400];
    CHECK_EQ(frame_encode(huge, sizeof huge, 0, keys40, v, 8), 0);
}

// ------------------------------------------------------------ rate command

// Feeds s (len bytes) and returns every accepted rate, in order, as a string.
static void feed(RateCommandParser &p, const char *s, size_t len, char *out, size_t cap) {
    out[0] = 0;
    for (size_t i = 0; i < len; ++i) {
        uint8_t n = p.feed((uint8_t)s[i]);
        if (n) snprintf(out + strlen(out), cap - strlen(out), "%s%u", out[0] ? "," : "", n);
    }
}

static void check_rates_n(const char *input, size_t len, const char *want) {
    RateCommandParser p;
    char got[128];
    feed(p, input, len, got, sizeof got);
    ++checks;
    if (strcmp(got, want) != 0) {
        ++failures;
        fprintf(stderr, "rate parser on \"%s\": accepted [%s], expected [%s]\n", input, got, want);
    }
}

static void check_rates(const char *input, const char *want) { check_rates_n(input, strlen(input), want); }

static void test_rate_command() {
    check_rates("rate=20#", "20");
    check_rates("rate=10#", "10");
    check_rates("rate=50#", "50");
    check_rates("rate=010#", "10");
    check_rates("rate=9#rate=51#rate=0#rate=#rate=1000#rate=0050#", "");
    check_rates("rate=30", "");                 // no '#' yet
    check_rates("rate=30#rate=40#", "30,40");
    check_rates("Rate=30#rate:30#rate=3a0#rate=-30#rate=30.0#", "");
    check_rates("xrate=30#rate=45#", "45");     // garbage before, then a valid command
    check_rates("garbage###rate=25#", "25");
    check_rates("rate=2rate=30#rate=33#", "33");
    check_rates("rate=30#\r\nrate=31#\r\n \t rate=32#\t", "30,31,32");  // line ends between commands
    check_rates_n("\x00rate=12#", 9, "12");
    check_rates_n("rate=12\x00#", 9, "");      // but not inside a command
    check_rates("rate=30\r\n#rate = 31#rate=32 #", "");
    check_rates("\xff\xfe\x80rate=15#", "");    // binary garbage rejects up to the '#'
    check_rates("\xff\xfe\x80#rate=15#", "15");

    // Byte by byte across separate calls, with the state kept between them.
    RateCommandParser p;
    char got[64];
    feed(p, "ra", 2, got, sizeof got);
    CHECK_STR(got, "");
    feed(p, "te=4", 4, got, sizeof got);
    CHECK_STR(got, "");
    feed(p, "8#", 2, got, sizeof got);
    CHECK_STR(got, "48");

    // Every byte value, then a valid command: never accepted by accident, and
    // the parser always recovers at the next '#'.
    for (int b = 0; b < 256; ++b) {
        RateCommandParser q;
        char in[16];
        size_t len = (size_t)snprintf(in, sizeof in, "%crate=27#", b);
        feed(q, in, len, got, sizeof got);
        bool ignorable = b == '\r' || b == '\n' || b == ' ' || b == '\t' || b == 0 || b == '#';
        CHECK_STR(got, ignorable ? "27" : "");
        feed(q, "rate=27#", 8, got, sizeof got);
        CHECK_STR(got, "27");
    }

    // A long run of pseudo-random bytes never produces an out-of-range rate.
    RateCommandParser r;
    uint32_t x = 12345;
    for (int i = 0; i < 200000; ++i) {
        x = x * 1103515245u + 12345u;
        uint8_t n = r.feed((uint8_t)(x >> 16));
        CHECK(n == 0 || (n >= FRAME_RATE_MIN_HZ && n <= FRAME_RATE_MAX_HZ));
    }
    feed(r, "#rate=33#", 9, got, sizeof got);
    CHECK_STR(got, "33");
}

// ------------------------------------------------------------ serial rate

// The defaults build.
static_assert(baud_supported(16000000UL, SERIAL_BAUD, FRAME_LONGEST_BYTES, FRAME_RATE_MAX_HZ),
              "the default BAUD passes its own rule");

static void test_longest_frame() {
    // FRAME_LONGEST_BYTES is what frame_encode writes at the longest values,
    // with and without the accelerometer (board_config.h).
    static const char *const no_acc[] = {"ir1", "ir2", "fsr0", "fsr1", "fsr2", "fsr3", "fsr4",
                                         "fsr5"};
    const uint16_t v[] = {1023, 1023, 1023, 1023, 1023, 1023, 1023, 1023, 1023, 1023, 1023};
    char buf[FRAME_BUF_SIZE];
    size_t with = frame_encode(buf, sizeof buf, 65535, kAllKeys, v, 11);
    size_t without = frame_encode(buf, sizeof buf, 65535, no_acc, v, 8);
    CHECK_EQ(with, 127);    // whexar.sensors.usart.LONGEST_FRAME_BYTES
    CHECK_EQ(without, 97);
    CHECK_EQ(FRAME_LONGEST_BYTES, WITH_ACCEL ? with : without);
}

static void test_baud_rule() {
    // Every rate of the datasheet's table at 16 MHz (Table 22-12) and its
    // 2 Mbps maximum: (rate, UBRR and U2X as Serial.begin() sets them, passes).
    struct Row {
        uint32_t baud;
        uint32_t ubrr;
        bool u2x;
        bool ok;
    };
    const Row rows[] = {
        {2400, 832, true, false},     // within 2 %, but too slow for the frames
        {4800, 416, true, false},     {9600, 207, true, false},
        {14400, 138, true, false},    {19200, 103, true, false},
        {28800, 68, true, false},     {38400, 51, true, false},
        {57600, 16, false, false},    // normal speed forced: +2.1 %
        {76800, 25, true, true},      // +0.2 %
        {115200, 16, true, false},    // +2.1 %
        {230400, 8, true, false},     // -3.5 %
        {250000, 7, true, true},      {500000, 3, true, true},
        {1000000, 1, true, true},     {2000000, 0, true, true},
    };
    for (const Row &r : rows) {
        CHECK_EQ(usart_ubrr(16000000UL, r.baud), r.ubrr);
        CHECK_EQ(usart_u2x(16000000UL, r.baud), r.u2x);
        CHECK_EQ(baud_supported(16000000UL, r.baud, 127, FRAME_RATE_MAX_HZ), r.ok);
    }
    // The USART alone: the slow rates are fine, 57600/115200/230400 are not.
    CHECK(usart_within_2pct(16000000UL, 9600));
    CHECK(usart_within_2pct(16000000UL, 28800));  // +0.6 %
    CHECK(!usart_within_2pct(16000000UL, 57600));
    CHECK(!usart_within_2pct(16000000UL, 115200));
    CHECK(!usart_within_2pct(16000000UL, 3000000));  // above f / 8
    CHECK(!usart_within_2pct(16000000UL, 0));
    // The frames: 127 bytes at 50 Hz need 63.5 kbps.
    CHECK(baud_carries_frames(63500, 127, 50));
    CHECK(!baud_carries_frames(63499, 127, 50));
}

int main() {
    test_filter_start_and_constant();
    test_filter_spike_never_shows();
    test_filter_steps();
    test_filter_trimmed_mean_rounding();
    test_crc();
    test_frame_example();
    test_frame_without_accel_and_extremes();
    test_frame_bounds();
    test_rate_command();
    test_longest_frame();
    test_baud_rule();
    if (failures) {
        fprintf(stderr, "host tests: %d of %d checks FAILED\n", failures, checks);
        return 1;
    }
    printf("host tests: %d checks passed\n", checks);
    return 0;
}
