/*
 * whexar-sim: runs the sensor-board firmware (ATmega2560, 16 MHz) in simavr
 * with chosen analog voltages and connects its UART0 to stdout or a pty.
 *
 *   whexar-sim [--elf PATH] [--mv CH=MV]... [--script FILE] [--duration-ms N]
 *              [--pty | --stdout] [--realtime] [--quiet]
 *
 * ADC model (simavr 1.6, sim/avr_adc.c): the result is
 *     ADC = min(1023, floor(mV * 1023 / Vref_mV))
 * with Vref = AVCC = 5000 mV here (Arduino's DEFAULT reference on the Mega).
 * A real ATmega2560 gives floor(Vin * 1024 / Vref) clipped to 1023
 * (datasheet 26.7), so the two can differ by one count.
 *
 * simavr 1.6 stores input voltages for ADC0..ADC7 only (avr_adc_t.adc_values[8];
 * ADC8..ADC15 would read whatever follows that array). The harness feeds the
 * channels it cannot hold through their mux entry instead: an ADC_MUX_REF
 * entry carrying the millivolts, which simavr scales with the same formula.
 */
#define _GNU_SOURCE
#include <ctype.h>
#include <errno.h>
#include <fcntl.h>
#include <libgen.h>
#include <limits.h>
#include <signal.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <termios.h>
#include <time.h>
#include <unistd.h>

#include <avr_adc.h>
#include <avr_uart.h>
#include <sim_avr.h>
#include <sim_elf.h>
#include <sim_io.h>
#include <sim_irq.h>
#include <sim_regbit.h>
#include <sim_time.h>

#define MCU_NAME "atmega2560"
#define F_CPU_HZ 16000000u     // Arduino Mega 2560 crystal
#define SUPPLY_MV 5000u        // VCC = AVCC = AREF on the Mega
#define N_ADC 16
#define TICK_US 1000u          // housekeeping period in simulated time
#define OUT_BUF 4096

/* ------------------------------------------------------------------ options */

typedef struct {
    uint64_t t_ms;
    int ch;            // ADC channel, or -1 for "send"
    uint32_t mv;
    char *text;        // for send
    size_t len;
} event_t;

static const char *opt_elf;
static int opt_pty;
static int opt_realtime;
static int opt_quiet;
static uint64_t opt_duration_ms;
static uint32_t initial_mv[N_ADC];
static event_t *events;
static size_t n_events, cap_events, next_event;

static void info(const char *fmt, ...) {
    if (opt_quiet) return;
    va_list ap;
    va_start(ap, fmt);
    fputs("whexar-sim: ", stderr);
    vfprintf(stderr, fmt, ap);
    va_end(ap);
}

static void die(const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    fputs("whexar-sim: ", stderr);
    vfprintf(stderr, fmt, ap);
    va_end(ap);
    exit(2);
}

static void usage(FILE *f) {
    fputs("usage: whexar-sim [--elf PATH] [--mv CH=MV]... [--script FILE] [--duration-ms N]\n"
          "                  [--pty | --stdout] [--realtime] [--quiet]\n"
          "  CH: ADC channel 0..15 or ir1 ir2 fsr0..fsr5 accx accy accz; MV: 0..5000\n"
          "  script lines: 'T_MS CH MV' or 'T_MS send TEXT' (escapes \\n \\r \\t \\0 \\\\ \\xHH)\n",
          f);
}

// Channel names as wired in whexar_sensors/board_config.h.
static int parse_channel(const char *s) {
    static const struct { const char *name; int ch; } names[] = {
        {"ir1", 0},  {"ir2", 1},  {"fsr0", 2}, {"fsr1", 3}, {"fsr2", 4},  {"fsr3", 5},
        {"fsr4", 6}, {"fsr5", 7}, {"accx", 8}, {"accy", 9}, {"accz", 10},
    };
    for (size_t i = 0; i < sizeof names / sizeof names[0]; ++i)
        if (strcmp(s, names[i].name) == 0) return names[i].ch;
    char *end;
    errno = 0;
    long v = strtol(s, &end, 10);
    if (*s && !*end && !errno && v >= 0 && v < N_ADC) return (int)v;
    return -1;
}

static int parse_u64(const char *s, uint64_t *out) {
    char *end;
    errno = 0;
    if (!*s || *s == '-') return -1;
    unsigned long long v = strtoull(s, &end, 10);
    if (*end || errno) return -1;
    *out = v;
    return 0;
}

static int parse_mv(const char *s, uint32_t *out) {
    uint64_t v;
    if (parse_u64(s, &v) || v > SUPPLY_MV) return -1;
    *out = (uint32_t)v;
    return 0;
}

static event_t *add_event(void) {
    if (n_events == cap_events) {
        cap_events = cap_events ? 2 * cap_events : 16;
        events = realloc(events, cap_events * sizeof *events);
        if (!events) die("out of memory\n");
    }
    event_t *e = &events[n_events++];
    memset(e, 0, sizeof *e);
    return e;
}

// Decodes \n \r \t \0 \\ \xHH in place; returns the decoded length.
static size_t unescape(char *s) {
    char *w = s;
    for (char *r = s; *r; ++r) {
        if (*r != '\\' || !r[1]) {
            *w++ = *r;
            continue;
        }
        ++r;
        switch (*r) {
        case 'n': *w++ = '\n'; break;
        case 'r': *w++ = '\r'; break;
        case 't': *w++ = '\t'; break;
        case '0': *w++ = '\0'; break;
        case 'x':
            if (isxdigit((unsigned char)r[1]) && isxdigit((unsigned char)r[2])) {
                char hex[3] = {r[1], r[2], 0};
                *w++ = (char)strtol(hex, NULL, 16);
                r += 2;
                break;
            }
            /* fall through */
        default: *w++ = *r; break;
        }
    }
    return (size_t)(w - s);
}

static void load_script(const char *path) {
    FILE *f = fopen(path, "r");
    if (!f) die("%s: %s\n", path, strerror(errno));
    char *line = NULL;
    size_t cap = 0;
    ssize_t n;
    int lineno = 0;
    while ((n = getline(&line, &cap, f)) >= 0) {
        ++lineno;
        while (n > 0 && (line[n - 1] == '\n' || line[n - 1] == '\r')) line[--n] = 0;
        char *p = line;
        while (isspace((unsigned char)*p)) ++p;
        if (!*p || *p == '#') continue;
        char *t = strsep(&p, " \t");
        while (p && isspace((unsigned char)*p)) ++p;
        char *what = p ? strsep(&p, " \t") : NULL;
        uint64_t t_ms;
        if (!what || parse_u64(t, &t_ms)) die("%s:%d: expected 'T_MS CH MV' or 'T_MS send TEXT'\n", path, lineno);
        event_t *e = add_event();
        e->t_ms = t_ms;
        if (strcmp(what, "send") == 0) {
            // TEXT is the rest of the line after one separator, escapes decoded.
            e->ch = -1;
            e->text = strdup(p ? p : "");
            if (!e->text) die("out of memory\n");
            e->len = unescape(e->text);
        } else {
            while (p && isspace((unsigned char)*p)) ++p;
            char *mv = p ? strsep(&p, " \t") : NULL;
            while (p && isspace((unsigned char)*p)) ++p;
            if ((e->ch = parse_channel(what)) < 0 || !mv || parse_mv(mv, &e->mv) ||
                (p && *p && *p != '#'))
                die("%s:%d: bad line (channel 0..15 or name, millivolts 0..5000)\n", path, lineno);
        }
    }
    free(line);
    fclose(f);
    // Sort by time, keeping file order for equal times (a stable insertion sort:
    // scripts are short).
    for (size_t i = 1; i < n_events; ++i) {
        event_t e = events[i];
        size_t j = i;
        while (j > 0 && events[j - 1].t_ms > e.t_ms) {
            events[j] = events[j - 1];
            --j;
        }
        events[j] = e;
    }
}

static void parse_args(int argc, char **argv) {
    for (int i = 1; i < argc; ++i) {
        const char *a = argv[i];
        const char *val = NULL;
        // Options taking a value accept "--opt VALUE" and "--opt=VALUE".
        const char *takes[] = {"--elf", "--mv", "--script", "--duration-ms"};
        for (size_t k = 0; k < 4; ++k) {
            size_t l = strlen(takes[k]);
            if (strncmp(a, takes[k], l) == 0 && (a[l] == 0 || a[l] == '=')) {
                if (a[l] == '=') val = a + l + 1;
                else if (i + 1 < argc) val = argv[++i];
                else die("%s needs a value\n", takes[k]);
                a = takes[k];
                break;
            }
        }
        if (strcmp(a, "--elf") == 0) {
            opt_elf = val;
        } else if (strcmp(a, "--mv") == 0) {
            char *copy = strdup(val);
            char *eq = copy ? strchr(copy, '=') : NULL;
            if (!eq) die("--mv expects CH=MV, got '%s'\n", val);
            *eq = 0;
            int ch = parse_channel(copy);
            uint32_t mv;
            if (ch < 0 || parse_mv(eq + 1, &mv)) die("--mv %s: channel 0..15 or name, millivolts 0..5000\n", val);
            initial_mv[ch] = mv;
            free(copy);
        } else if (strcmp(a, "--script") == 0) {
            load_script(val);
        } else if (strcmp(a, "--duration-ms") == 0) {
            if (parse_u64(val, &opt_duration_ms)) die("--duration-ms expects a number of ms\n");
        } else if (strcmp(a, "--pty") == 0) {
            opt_pty = 1;
        } else if (strcmp(a, "--stdout") == 0) {
            opt_pty = 0;
        } else if (strcmp(a, "--realtime") == 0) {
            opt_realtime = 1;
        } else if (strcmp(a, "--quiet") == 0) {
            opt_quiet = 1;
        } else if (strcmp(a, "-h") == 0 || strcmp(a, "--help") == 0) {
            usage(stdout);
            exit(0);
        } else {
            usage(stderr);
            die("unknown argument '%s'\n", a);
        }
    }
}

// <directory of this binary>/whexar_sensors.elf
static char *default_elf(const char *argv0) {
    char self[PATH_MAX];
    ssize_t n = readlink("/proc/self/exe", self, sizeof self - 1);
    if (n > 0) self[n] = 0;
    else snprintf(self, sizeof self, "%s", argv0);
    char *dir = dirname(self);
    char *path;
    if (asprintf(&path, "%s/whexar_sensors.elf", dir) < 0) die("out of memory\n");
    return path;
}

/* ------------------------------------------------------------------ state */

static avr_t *avr;
static avr_adc_t *adc;
static avr_uart_t *uart0;
static avr_irq_t *adc_irq, *uart_irq;
static int direct_channels;          // channels simavr's ADC module stores itself
static int mux_index[N_ADC];         // muxmode slot of single-ended channel n, or -1

static volatile sig_atomic_t stop_signal;
static int out_fd = STDOUT_FILENO;   // stdout or the pty master
static int pty_master = -1, pty_slave = -1;
static uint8_t out_buf[OUT_BUF];
static size_t out_len;
static uint64_t tx_bytes, tx_frames, tx_dropped;
static int out_closed;

// Bytes waiting to enter the UART's receive side (script "send" and pty input).
static uint8_t *rx_queue;
static size_t rx_len, rx_cap, rx_head;
static int rx_xoff;
static int rx_timer_armed;
static uint64_t rx_bytes;

static struct timespec wall_start;

static uint64_t now_ns(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (uint64_t)t.tv_sec * 1000000000u + (uint64_t)t.tv_nsec;
}

static uint64_t wall_elapsed_ns(void) {
    return now_ns() - ((uint64_t)wall_start.tv_sec * 1000000000u + (uint64_t)wall_start.tv_nsec);
}

static uint64_t sim_ns(void) { return avr_cycles_to_nsec(avr, avr->cycle); }

/* ------------------------------------------------------------------ ADC */

static avr_io_t *find_io(const char *kind, char uart_name) {
    for (avr_io_t *io = avr->io_port; io; io = io->next) {
        if (strcmp(io->kind, kind) != 0) continue;
        if (uart_name && ((avr_uart_t *)io)->name != uart_name) continue;
        return io;
    }
    return NULL;
}

static void set_mv(int ch, uint32_t mv) {
    if (ch < direct_channels) {
        avr_raise_irq(adc_irq + ADC_IRQ_ADC0 + ch, mv);
    } else if (mux_index[ch] >= 0) {
        // simavr reads ADC_MUX_REF entries as "src" millivolts and scales them
        // like a pin voltage: the same result as a real input of mv.
        avr_adc_mux_t m = {.kind = ADC_MUX_REF, .src = mv};
        adc->muxmode[mux_index[ch]] = m;
    }
}

static void setup_adc(void) {
    adc = (avr_adc_t *)find_io("adc", 0);
    if (!adc) die("no ADC in the simulated " MCU_NAME "\n");
    adc_irq = avr_io_getirq(avr, AVR_IOCTL_ADC_GETIRQ, 0);
    direct_channels = (int)(sizeof adc->adc_values / sizeof adc->adc_values[0]);
    if (direct_channels > N_ADC) direct_channels = N_ADC;
    for (int ch = 0; ch < N_ADC; ++ch) mux_index[ch] = -1;
    for (int i = 0; i < (int)(sizeof adc->muxmode / sizeof adc->muxmode[0]); ++i) {
        avr_adc_mux_t m = adc->muxmode[i];
        if (m.kind == ADC_MUX_SINGLE && m.src < N_ADC && mux_index[m.src] < 0) mux_index[m.src] = i;
    }
    for (int ch = 0; ch < N_ADC; ++ch) set_mv(ch, initial_mv[ch]);
}

/* ------------------------------------------------------------------ UART */

static void flush_out(void) {
    size_t off = 0;
    while (off < out_len && !out_closed) {
        ssize_t n = write(out_fd, out_buf + off, out_len - off);
        if (n > 0) {
            off += (size_t)n;
        } else if (n < 0 && errno == EINTR) {
            continue;
        } else if (opt_pty) {
            // Nobody reads the pty (buffer full) or nobody has it open: a
            // serial line drops what no one receives.
            tx_dropped += out_len - off;
            break;
        } else {
            if (errno == EPIPE) info("stdout closed, stopping\n");
            else info("write to stdout: %s\n", strerror(errno));
            out_closed = 1;
            stop_signal = 1;
        }
    }
    out_len = 0;
}

static void uart_tx(avr_irq_t *irq, uint32_t value, void *param) {
    (void)irq;
    (void)param;
    ++tx_bytes;
    if (value == '#') ++tx_frames;
    if (out_len == OUT_BUF) flush_out();
    out_buf[out_len++] = (uint8_t)value;
}

static void uart_xoff(avr_irq_t *irq, uint32_t value, void *param) {
    (void)irq;
    (void)value;
    (void)param;
    rx_xoff = 1;
}

static void uart_xon(avr_irq_t *irq, uint32_t value, void *param) {
    (void)irq;
    (void)value;
    (void)param;
    rx_xoff = 0;
}

// One byte time on the wire (10 bits at the baud rate the firmware set).
static avr_cycle_count_t byte_cycles(void) {
    if (uart0 && uart0->cycles_per_byte) return uart0->cycles_per_byte;
    return avr_usec_to_cycles(avr, 10);  // 1 Mbps
}

static avr_cycle_count_t rx_feed(avr_t *a, avr_cycle_count_t when, void *param) {
    (void)a;
    (void)param;
    // Bytes that arrive before the firmware enables its receiver wait for it
    // (a real board would lose them; a host that writes right after opening
    // the pty should not have to guess when Serial.begin() ran).
    if (uart0 && !avr_regbit_get(avr, uart0->rxen)) return when + avr_usec_to_cycles(avr, 100);
    if (rx_head < rx_len && !rx_xoff) {
        avr_raise_irq(uart_irq + UART_IRQ_INPUT, rx_queue[rx_head++]);
        ++rx_bytes;
    }
    if (rx_head < rx_len) return when + byte_cycles();
    rx_head = rx_len = 0;
    rx_timer_armed = 0;
    return 0;
}

static void rx_enqueue(const uint8_t *data, size_t len) {
    if (!len) return;
    if (rx_len + len > rx_cap) {
        rx_cap = (rx_len + len) * 2;
        rx_queue = realloc(rx_queue, rx_cap);
        if (!rx_queue) die("out of memory\n");
    }
    memcpy(rx_queue + rx_len, data, len);
    rx_len += len;
    if (!rx_timer_armed) {
        rx_timer_armed = 1;
        avr_cycle_timer_register(avr, byte_cycles(), rx_feed, NULL);
    }
}

static void setup_uart(void) {
    uint32_t flags = 0;
    avr_ioctl(avr, AVR_IOCTL_UART_GET_FLAGS('0'), &flags);
    // No console echo of the output, no usleep() when the firmware polls UDR.
    flags &= ~(uint32_t)(AVR_UART_FLAG_STDIO | AVR_UART_FLAG_POLL_SLEEP);
    avr_ioctl(avr, AVR_IOCTL_UART_SET_FLAGS('0'), &flags);
    uart0 = (avr_uart_t *)find_io("uart", '0');
    uart_irq = avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ('0'), 0);
    avr_irq_register_notify(uart_irq + UART_IRQ_OUTPUT, uart_tx, NULL);
    avr_irq_register_notify(uart_irq + UART_IRQ_OUT_XOFF, uart_xoff, NULL);
    avr_irq_register_notify(uart_irq + UART_IRQ_OUT_XON, uart_xon, NULL);
}

/* ------------------------------------------------------------------ pty */

static void open_pty(void) {
    pty_master = posix_openpt(O_RDWR | O_NOCTTY);
    if (pty_master < 0 || grantpt(pty_master) || unlockpt(pty_master)) die("pty: %s\n", strerror(errno));
    const char *name = ptsname(pty_master);
    if (!name) die("ptsname: %s\n", strerror(errno));
    // Hold the slave open: its raw termios then persists, and a reader that
    // closes and reopens it never hangs up the master (no EIO loop).
    pty_slave = open(name, O_RDWR | O_NOCTTY);
    if (pty_slave < 0) die("%s: %s\n", name, strerror(errno));
    struct termios tio;
    if (tcgetattr(pty_slave, &tio) == 0) {
        cfmakeraw(&tio);
        tcsetattr(pty_slave, TCSANOW, &tio);
    }
    fcntl(pty_master, F_SETFL, fcntl(pty_master, F_GETFL) | O_NONBLOCK);
    out_fd = pty_master;
    printf("pty: %s\n", name);
    fflush(stdout);
}

static void poll_pty(void) {
    uint8_t buf[256];
    for (;;) {
        ssize_t n = read(pty_master, buf, sizeof buf);
        if (n > 0) {
            rx_enqueue(buf, (size_t)n);
            continue;
        }
        if (n < 0 && errno == EINTR) continue;
        break;  // EAGAIN: nothing written; EIO: no reader (cannot happen while we hold the slave)
    }
}

/* ------------------------------------------------------------------ time */

static avr_cycle_count_t tick(avr_t *a, avr_cycle_count_t when, void *param) {
    (void)a;
    (void)param;
    uint64_t t_ms = sim_ns() / 1000000u;
    while (next_event < n_events && events[next_event].t_ms <= t_ms) {
        event_t *e = &events[next_event++];
        if (e->ch >= 0) set_mv(e->ch, e->mv);
        else rx_enqueue((const uint8_t *)e->text, e->len);
    }
    if (opt_pty) poll_pty();
    if (out_len) flush_out();
    if (opt_realtime) {
        // Never let simulated time run ahead of the wall clock.
        uint64_t s = sim_ns(), w = wall_elapsed_ns();
        if (s > w) {
            uint64_t d = s - w;
            struct timespec ts = {(time_t)(d / 1000000000u), (long)(d % 1000000000u)};
            while (nanosleep(&ts, &ts) < 0 && errno == EINTR && !stop_signal) {}
        }
    }
    return when + avr_usec_to_cycles(avr, TICK_US);
}

static void on_signal(int sig) {
    (void)sig;
    stop_signal = 1;
}

// simavr's own messages go to stderr (its default logger writes some to
// stdout, which carries the UART bytes), errors and warnings only.
static void logger(avr_t *a, const int level, const char *fmt, va_list ap) {
    (void)a;
    if (opt_quiet || level > LOG_WARNING) return;
    fputs("simavr: ", stderr);
    vfprintf(stderr, fmt, ap);
}

// simavr's default sleep callback usleep()s for the time the AVR sleeps,
// tying the simulation to wall time; pacing is done in tick() instead.
static void no_sleep(avr_t *a, avr_cycle_count_t how_long) {
    (void)a;
    (void)how_long;
}

/* ------------------------------------------------------------------ main */

int main(int argc, char **argv) {
    parse_args(argc, argv);
    if (!opt_elf) opt_elf = default_elf(argv[0]);

    avr_global_logger_set(logger);

    elf_firmware_t fw;
    memset(&fw, 0, sizeof fw);
    if (access(opt_elf, R_OK) != 0) die("%s: %s\n", opt_elf, strerror(errno));
    if (elf_read_firmware(opt_elf, &fw) != 0) die("%s: cannot read the ELF\n", opt_elf);
    fw.frequency = F_CPU_HZ;
    fw.vcc = fw.avcc = fw.aref = SUPPLY_MV;

    avr = avr_make_mcu_by_name(MCU_NAME);
    if (!avr) die("simavr does not know the " MCU_NAME "\n");
    avr_init(avr);
    avr->log = opt_quiet ? LOG_NONE : LOG_WARNING;
    avr_load_firmware(avr, &fw);
    avr->frequency = F_CPU_HZ;
    avr->vcc = avr->avcc = avr->aref = SUPPLY_MV;
    avr->sleep = no_sleep;

    setup_adc();
    setup_uart();

    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_signal;
    sigaction(SIGINT, &sa, NULL);
    sigaction(SIGTERM, &sa, NULL);
    signal(SIGPIPE, SIG_IGN);

    if (opt_pty) open_pty();

    // Events at time 0 apply before the first instruction.
    clock_gettime(CLOCK_MONOTONIC, &wall_start);
    tick(avr, 0, NULL);
    avr_cycle_timer_register(avr, avr_usec_to_cycles(avr, TICK_US), tick, NULL);

    info("%s on %s at %u MHz, %s%s, %s\n", opt_elf, MCU_NAME, F_CPU_HZ / 1000000u,
         opt_pty ? "pty" : "stdout", opt_realtime ? ", real time" : "",
         opt_duration_ms ? "for a fixed time" : "until stopped");

    avr_cycle_count_t end_cycle = opt_duration_ms ? avr_usec_to_cycles(avr, 1000) * opt_duration_ms : 0;
    int state = cpu_Running;
    while (!stop_signal) {
        state = avr_run(avr);
        if (state == cpu_Done || state == cpu_Crashed) break;
        if (end_cycle && avr->cycle >= end_cycle) break;
    }
    flush_out();

    double sim_s = (double)sim_ns() / 1e9, wall_s = (double)wall_elapsed_ns() / 1e9;
    info("stopped at %.3f s simulated after %.3f s wall (%.1fx real time): %llu bytes, %llu frames sent,"
         " %llu bytes received%s\n",
         sim_s, wall_s, wall_s > 0 ? sim_s / wall_s : 0.0, (unsigned long long)tx_bytes,
         (unsigned long long)tx_frames, (unsigned long long)rx_bytes,
         state == cpu_Crashed ? " (firmware crashed)" : "");
    if (uart0) {
        // The rate the firmware programmed: F_CPU / (8 or 16 (UBRR + 1)), datasheet Table 22-1.
        unsigned ubrr = (unsigned)avr_regbit_get(avr, uart0->ubrrl) |
                        ((unsigned)avr_regbit_get(avr, uart0->ubrrh) << 8);
        unsigned u2x = avr_regbit_get(avr, uart0->u2x) ? 1u : 0u;
        info("uart0: %.0f bps (U2X=%u, UBRR=%u)\n",
             (double)F_CPU_HZ / ((u2x ? 8.0 : 16.0) * (ubrr + 1)), u2x, ubrr);
    }
    if (tx_dropped) info("%llu bytes dropped (no pty reader)\n", (unsigned long long)tx_dropped);
    if (pty_slave >= 0) close(pty_slave);
    if (pty_master >= 0) close(pty_master);
    avr_terminate(avr);
    return state == cpu_Crashed ? 1 : 0;
}
