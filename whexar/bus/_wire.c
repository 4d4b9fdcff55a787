/* whexar.bus._wire: the cycle's Dynamixel transactions in compiled code.
 *
 * What the bus does every cycle, and only that (the rest stays dynamixel-sdk's):
 * build an instruction packet (a Sync Read request, a Sync Write of goals), and
 * collect the status packets of a Sync Read or a Fast Sync Read.  The collecting
 * is dynamixel-sdk 4.1's own algorithm, step for step (Protocol2PacketHandler
 * rxPacket, readRx, fastSyncReadRx, removeStuffing; txPacket for the packets), so that every stream of bytes -- whole, corrupted, short,
 * interleaved -- gives the result the SDK's path gives; whexar.bus.wire says how
 * that is tested.
 *
 * Two ways in:
 *   parse()    -- over bytes already received (an emulated or replayed port);
 *   transact() -- on a serial port's file descriptor: write the request, then wait
 *                 in poll() with the GIL released while the statuses arrive,
 *                 parse as they come, send the packets that ride on the read as
 *                 soon as the last status is whole, and hand back what was read
 *                 and when, for the link taps.
 *
 * Protocol 2.0 (ROBOTIS e-manual): FF FF FD 00 | ID | LEN_L LEN_H | INST | params |
 * CRC_L CRC_H; a status has INST 0x55 and ERR first among its parameters.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>

#include <errno.h>
#include <math.h>
#include <poll.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

/* dynamixel-sdk's result codes (robotis_def.py); whexar.bus.wire checks them equal. */
#define COMM_SUCCESS 0
#define COMM_TX_FAIL (-1001)
#define COMM_RX_TIMEOUT (-3001)
#define COMM_RX_CORRUPT (-3002)

#define TXPACKET_MAX_LEN 1024 /* protocol2_packet_handler.py */
#define RXPACKET_MAX_LEN 1024
#define MAX_ID 0xFC
#define BROADCAST_ID 0xFE
#define INST_STATUS 0x55
#define MAX_SERVOS 253
#define RX_CAP (1 << 20) /* bytes kept per transaction: far beyond any reply */

static uint16_t crc_table[256];

static void build_crc_table(void)
{
    /* CRC-16, polynomial 0x8005, MSB first, initial 0: the SDK's updateCRC table. */
    for (int i = 0; i < 256; i++) {
        uint16_t c = (uint16_t)(i << 8);
        for (int b = 0; b < 8; b++)
            c = (uint16_t)((c & 0x8000) ? (c << 1) ^ 0x8005 : c << 1);
        crc_table[i] = c;
    }
}

static uint16_t crc16(uint16_t crc, const uint8_t *p, Py_ssize_t n)
{
    for (Py_ssize_t i = 0; i < n; i++)
        crc = (uint16_t)((crc << 8) ^ crc_table[((crc >> 8) ^ p[i]) & 0xFF]);
    return crc;
}

static double now_s(void)
{
    /* CLOCK_MONOTONIC: the clock Python's time.monotonic() reads on Linux. */
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + (double)ts.tv_nsec * 1e-9;
}

/* ------------------------------------------------------------------ packets */

/* The instruction packet txPacket sends for (ident, inst, params): the header, the
 * parameters as they are, the CRC.  As they are: txPacket calls addStuffing and drops
 * what it returns, and addStuffing changes the packet it was given only where there was
 * nothing to stuff (dynamixel-sdk 4.1, protocol2_packet_handler.py), so the SDK sends
 * every packet unstuffed.  Returns the length, or -1 when the SDK refuses it (longer
 * than TXPACKET_MAX_LEN). */
static Py_ssize_t build_packet(uint8_t *out, int ident, int inst, const uint8_t *params,
                               Py_ssize_t nparams)
{
    Py_ssize_t length = nparams + 3, total = length + 7;
    if (total > TXPACKET_MAX_LEN)
        return -1;
    out[0] = 0xFF, out[1] = 0xFF, out[2] = 0xFD, out[3] = 0x00;
    out[4] = (uint8_t)ident;
    out[5] = (uint8_t)(length & 0xFF), out[6] = (uint8_t)(length >> 8);
    out[7] = (uint8_t)inst;
    memcpy(out + 8, params, (size_t)nparams);
    uint16_t crc = crc16(0, out, total - 2);
    out[total - 2] = (uint8_t)(crc & 0xFF), out[total - 1] = (uint8_t)(crc >> 8);
    return total;
}

/* ------------------------------------------------------------------ the SDK's receiver */

typedef struct {
    const uint8_t *buf;
    Py_ssize_t avail; /* bytes received so far */
    Py_ssize_t pos;   /* bytes the SDK has taken with readPort() */
    int timed_out;    /* the deadline has passed: a port with nothing left times out */
    int hit_timeout;  /* isPacketTimeout() said yes (the taps report it) */
} Stream;

enum { NEED_MORE = 0, DONE = 1 };

/* One rxPacket(): the window it ends with is buf[*start, *start + *rx). */
static int rx_packet(Stream *s, int max_id, int *result, Py_ssize_t *start_out,
                     Py_ssize_t *rx_out, Py_ssize_t *wait_out)
{
    Py_ssize_t start = s->pos, rx = 0, wait = 11;
    for (;;) {
        /* readPort(wait - rx): up to that many unread bytes; a negative count slices
         * the unread bytes as Python does, all but the last -n. */
        Py_ssize_t n = wait - rx, unread = s->avail - s->pos, take;
        if (n >= 0)
            take = n < unread ? n : unread;
        else
            take = unread + n > 0 ? unread + n : 0;
        s->pos += take;
        rx += take;
        if (rx >= wait) {
            const uint8_t *p = s->buf + start;
            Py_ssize_t idx;
            for (idx = 0; idx < rx - 3; idx++)
                if (p[idx] == 0xFF && p[idx + 1] == 0xFF && p[idx + 2] == 0xFD &&
                    p[idx + 3] != 0xFD)
                    break;
            if (idx == rx - 3)
                idx = rx - 4; /* a Python for loop that ran out leaves its last value */
            if (idx == 0) {
                Py_ssize_t length = p[5] | (p[6] << 8);
                if (p[3] != 0x00 || p[4] > max_id || length > RXPACKET_MAX_LEN ||
                    p[7] != INST_STATUS) {
                    start++, rx--; /* drop the first byte */
                    continue;
                }
                if (wait != length + 7) {
                    wait = length + 7;
                    continue;
                }
                uint16_t crc = (uint16_t)(p[wait - 2] | (p[wait - 1] << 8));
                *result = crc16(0, p, wait - 2) == crc ? COMM_SUCCESS : COMM_RX_CORRUPT;
                break;
            }
            start += idx, rx -= idx; /* drop what comes before the header */
        } else {
            /* Nothing left to read: isPacketTimeout() decides. */
            if (!s->timed_out)
                return NEED_MORE;
            s->hit_timeout = 1;
            *result = rx == 0 ? COMM_RX_TIMEOUT : COMM_RX_CORRUPT;
            break;
        }
    }
    *start_out = start, *rx_out = rx, *wait_out = wait;
    return DONE;
}

/* The SDK's removeStuffing, in place and literally (it reads what it has written). */
static void remove_stuffing(uint8_t *p)
{
    Py_ssize_t len_in = p[5] | (p[6] << 8), len_out = len_in, index = 7;
    for (Py_ssize_t i = 0; i < len_in - 2; i++) {
        if (p[i + 7] == 0xFD && p[i + 8] == 0xFD && p[i + 6] == 0xFF && p[i + 5] == 0xFF)
            len_out--;
        else
            p[index++] = p[i + 7];
    }
    p[index] = p[7 + len_in - 2];
    p[index + 1] = p[7 + len_in - 1];
    p[5] = (uint8_t)(len_out & 0xFF), p[6] = (uint8_t)((len_out >> 8) & 0xFF);
}

typedef struct {
    int result;
    Py_ssize_t failed;      /* index of the servo that failed, -1 on success */
    Py_ssize_t done;        /* servos decoded */
    Py_ssize_t off[MAX_SERVOS], len[MAX_SERVOS];
    uint8_t err[MAX_SERVOS];
    uint8_t *arena;         /* the servos' data, back to back */
    Py_ssize_t arena_used;
    uint8_t *scratch;       /* one window, to unstuff */
    Py_ssize_t scratch_cap;
} Parsed;

static int grow_scratch(Parsed *o, Py_ssize_t n)
{
    if (n <= o->scratch_cap)
        return 0;
    uint8_t *p = realloc(o->scratch, (size_t)n);
    if (p == NULL)
        return -1;
    o->scratch = p, o->scratch_cap = n;
    return 0;
}

/* DxlBus._rx over the SDK: readRx for each servo in turn (a status of another ID is
 * read and passed over), stopping at the first failure.  Returns NEED_MORE, DONE, or
 * -1 out of memory. */
static int parse_plain(Stream *s, const uint8_t *ids, Py_ssize_t n, Py_ssize_t length,
                       Parsed *o)
{
    o->result = COMM_SUCCESS, o->failed = -1, o->done = 0, o->arena_used = 0;
    for (Py_ssize_t k = 0; k < n; k++) {
        for (;;) {
            int result;
            Py_ssize_t start, rx, wait;
            if (rx_packet(s, MAX_ID, &result, &start, &rx, &wait) == NEED_MORE)
                return NEED_MORE;
            if (result != COMM_SUCCESS) {
                o->result = result, o->failed = k;
                return DONE;
            }
            if (grow_scratch(o, rx) < 0)
                return -1;
            memcpy(o->scratch, s->buf + start, (size_t)rx);
            remove_stuffing(o->scratch);
            if (o->scratch[4] != ids[k])
                continue;
            /* data = rxpacket[9 : 9 + length], as far as the window goes */
            Py_ssize_t from = 9 < rx ? 9 : rx, to = 9 + length < rx ? 9 + length : rx;
            o->off[k] = o->arena_used, o->len[k] = to - from;
            memcpy(o->arena + o->arena_used, o->scratch + from, (size_t)(to - from));
            o->arena_used += to - from;
            o->err[k] = o->scratch[8];
            o->done = k + 1;
            break;
        }
    }
    return DONE;
}

/* fastSyncReadRx: one status from 0xFE, not unstuffed; the data is
 * rxpacket[8 : 8 + (length + 4) * n], or nothing when the ID is not 0xFE. */
static int parse_fast(Stream *s, Py_ssize_t n, Py_ssize_t length, Parsed *o)
{
    int result;
    Py_ssize_t start, rx, wait;
    o->result = COMM_SUCCESS, o->failed = -1, o->done = 0, o->arena_used = 0;
    if (rx_packet(s, BROADCAST_ID, &result, &start, &rx, &wait) == NEED_MORE)
        return NEED_MORE;
    o->result = result;
    o->off[0] = 0, o->len[0] = 0;
    if (result != COMM_SUCCESS) {
        o->failed = 0;
        return DONE;
    }
    const uint8_t *p = s->buf + start;
    if (p[4] == BROADCAST_ID) {
        Py_ssize_t want = (length + 4) * n;
        Py_ssize_t from = 8 < rx ? 8 : rx, to = 8 + want < rx ? 8 + want : rx;
        if (grow_scratch(o, to - from) < 0)
            return -1;
        memcpy(o->scratch, p + from, (size_t)(to - from));
        o->len[0] = to - from;
    }
    return DONE;
}

static int parse_any(Stream *s, const uint8_t *ids, Py_ssize_t n, Py_ssize_t length,
                     int fast, Parsed *o)
{
    return fast ? parse_fast(s, n, length, o) : parse_plain(s, ids, n, length, o);
}

static int parsed_init(Parsed *o, Py_ssize_t n, Py_ssize_t length)
{
    memset(o, 0, sizeof *o);
    o->arena = malloc((size_t)(n * length + 1));
    return o->arena == NULL ? -1 : 0;
}

static void parsed_free(Parsed *o)
{
    free(o->arena);
    free(o->scratch);
}

/* (result, failed index or None, data, errors): data {id: bytes} and errors {id: ERR}
 * for a plain read, the raw bytes for a fast one (whexar.bus.wire splits them). */
static PyObject *parsed_result(Parsed *o, const uint8_t *ids, int fast)
{
    PyObject *data = NULL, *errors = NULL;
    if (fast) {
        data = PyBytes_FromStringAndSize((const char *)o->scratch, o->len[0]);
        errors = PyDict_New();
    } else {
        data = PyDict_New();
        errors = PyDict_New();
        if (data != NULL && errors != NULL) {
            for (Py_ssize_t k = 0; k < o->done; k++) {
                PyObject *key = PyLong_FromLong(ids[k]);
                PyObject *value = PyBytes_FromStringAndSize(
                    (const char *)o->arena + o->off[k], o->len[k]);
                PyObject *err = PyLong_FromLong(o->err[k]);
                int bad = key == NULL || value == NULL || err == NULL ||
                          PyDict_SetItem(data, key, value) < 0 ||
                          PyDict_SetItem(errors, key, err) < 0;
                Py_XDECREF(key), Py_XDECREF(value), Py_XDECREF(err);
                if (bad) {
                    Py_CLEAR(data);
                    break;
                }
            }
        }
    }
    if (data == NULL || errors == NULL) {
        Py_XDECREF(data), Py_XDECREF(errors);
        return NULL;
    }
    PyObject *failed = o->failed < 0 ? Py_NewRef(Py_None) : PyLong_FromSsize_t(o->failed);
    return Py_BuildValue("(iNNN)", o->result, failed, data, errors);
}

static int check_ids(Py_buffer *ids)
{
    if (ids->len < 1 || ids->len > MAX_SERVOS) {
        PyErr_SetString(PyExc_ValueError, "ids: between 1 and 253 servos");
        return -1;
    }
    return 0;
}

/* ------------------------------------------------------------------ Python API */

PyDoc_STRVAR(crc16_doc, "crc16(data, crc=0) -> int\n\n"
                        "CRC-16 (polynomial 0x8005) of data continuing from crc: the SDK's "
                        "updateCRC.");

static PyObject *py_crc16(PyObject *self, PyObject *args)
{
    Py_buffer data;
    unsigned int crc = 0;
    if (!PyArg_ParseTuple(args, "y*|I", &data, &crc))
        return NULL;
    uint16_t out = crc16((uint16_t)crc, data.buf, data.len);
    PyBuffer_Release(&data);
    return PyLong_FromLong(out);
}

PyDoc_STRVAR(packet_doc, "packet(ident, instruction, params) -> bytes | None\n\n"
                         "The instruction packet dynamixel-sdk's txPacket writes (with its CRC, "
                         "unstuffed as the SDK sends it); None where the SDK refuses it (too "
                         "long).");

static PyObject *py_packet(PyObject *self, PyObject *args)
{
    int ident, inst;
    Py_buffer params;
    if (!PyArg_ParseTuple(args, "iiy*", &ident, &inst, &params))
        return NULL;
    uint8_t out[TXPACKET_MAX_LEN];
    Py_ssize_t n = params.len <= TXPACKET_MAX_LEN
                       ? build_packet(out, ident, inst, params.buf, params.len)
                       : -1;
    PyBuffer_Release(&params);
    if (n < 0)
        Py_RETURN_NONE;
    return PyBytes_FromStringAndSize((const char *)out, n);
}

PyDoc_STRVAR(parse_doc,
             "parse(received, ids, length, fast, timed_out) -> (done, taken, result, failed, "
             "data, errors, timeout)\n\n"
             "dynamixel-sdk's reading of a Sync Read's statuses from the bytes received so "
             "far. done is False when it needs more bytes and timed_out is not set; taken "
             "is how many bytes the SDK would have read from the port; timeout, whether it "
             "asked isPacketTimeout() and was told yes.");

static PyObject *py_parse(PyObject *self, PyObject *args)
{
    Py_buffer buf, ids;
    Py_ssize_t length;
    int fast, timed_out;
    if (!PyArg_ParseTuple(args, "y*y*npp", &buf, &ids, &length, &fast, &timed_out))
        return NULL;
    PyObject *out = NULL;
    Parsed o;
    if (check_ids(&ids) < 0 || length < 0) {
        if (!PyErr_Occurred())
            PyErr_SetString(PyExc_ValueError, "length must be >= 0");
        goto done;
    }
    if (parsed_init(&o, ids.len, length) < 0) {
        PyErr_NoMemory();
        goto done;
    }
    Stream s = {buf.buf, buf.len, 0, timed_out, 0};
    int r = parse_any(&s, ids.buf, ids.len, length, fast, &o);
    if (r < 0)
        PyErr_NoMemory();
    else if (r == NEED_MORE)
        out = Py_BuildValue("(OniOOOO)", Py_False, s.pos, 0, Py_None, Py_None, Py_None,
                            Py_False);
    else {
        PyObject *res = parsed_result(&o, ids.buf, fast);
        if (res != NULL) {
            out = Py_BuildValue("(OnOOOOO)", Py_True, s.pos, PyTuple_GET_ITEM(res, 0),
                                PyTuple_GET_ITEM(res, 1), PyTuple_GET_ITEM(res, 2),
                                PyTuple_GET_ITEM(res, 3), s.hit_timeout ? Py_True : Py_False);
            Py_DECREF(res);
        }
    }
    parsed_free(&o);
done:
    PyBuffer_Release(&buf);
    PyBuffer_Release(&ids);
    return out;
}

/* A real port's transaction, without the GIL. */

typedef struct {
    char kind;    /* 't' tx, 'r' rx, 'o' timeout */
    double t;
    Py_ssize_t packet; /* tx: which packet (-1 the request) */
    Py_ssize_t off, len; /* rx: where in the received bytes */
} Event;

typedef struct {
    Event *ev;
    Py_ssize_t n, cap;
} Events;

static int add_event(Events *e, char kind, double t, Py_ssize_t packet, Py_ssize_t off,
                     Py_ssize_t len)
{
    if (e->n == e->cap) {
        Py_ssize_t cap = e->cap ? e->cap * 2 : 32;
        Event *p = realloc(e->ev, (size_t)cap * sizeof *p);
        if (p == NULL)
            return -1;
        e->ev = p, e->cap = cap;
    }
    e->ev[e->n++] = (Event){kind, t, packet, off, len};
    return 0;
}

#define USB_FLUSH_S 1e-3
/* A USB-serial adapter hands bytes over when its latency timer expires (1 ms once set
 * right, config/99-whexar-dynamixel.rules): a millisecond's bytes may be on their way. */
#define SLEEP_MIN_S 3e-4 /* a shorter sleep than this: wait in poll() instead */

static void sleep_until(double t)
{
    struct timespec ts;
    ts.tv_sec = (time_t)t;
    ts.tv_nsec = (long)((t - (double)ts.tv_sec) * 1e9);
    while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, NULL) == EINTR)
        ;
}

/* Write all of data; 0, or an errno (ETIMEDOUT when the port takes nothing for 1 s). */
static int write_all(int fd, const uint8_t *data, Py_ssize_t n)
{
    while (n > 0) {
        ssize_t w = write(fd, data, (size_t)n);
        if (w > 0) {
            data += w, n -= w;
            continue;
        }
        if (w < 0 && errno == EINTR)
            continue;
        if (w < 0 && errno != EAGAIN && errno != EWOULDBLOCK)
            return errno;
        struct pollfd pfd = {fd, POLLOUT, 0};
        int r = poll(&pfd, 1, 1000);
        if (r == 0)
            return ETIMEDOUT;
        if (r < 0 && errno != EINTR)
            return errno;
    }
    return 0;
}

/* Write the packets of then from *n_sent on, each reported as an event; *free_at moves
 * to when the bus is free of them (their bytes' wire time).  0, or an errno. */
static int send_then(int fd, Py_buffer *packets, Py_ssize_t n_then, Py_ssize_t *n_sent,
                     int *sent, Events *ev, double byte_s, double *free_at, int *memory)
{
    for (; *n_sent < n_then; (*n_sent)++) {
        Py_buffer *p = &packets[*n_sent];
        int error = write_all(fd, p->buf, p->len);
        if (error != 0)
            return error;
        double at = now_s();
        if (add_event(ev, 't', at, *n_sent, 0, 0) < 0)
            *memory = 1;
        *free_at = (at > *free_at ? at : *free_at) + (double)p->len * byte_s;
        sent[*n_sent] = COMM_SUCCESS;
    }
    return 0;
}

/* The last servo's status lies whole at the end of what was received (DxlBus's
 * _tail_complete): nothing more will answer, the half-duplex bus is free. */
static int tail_complete(const uint8_t *buf, Py_ssize_t n_buf, int last, Py_ssize_t length)
{
    Py_ssize_t n = 11 + length;
    if (n_buf < n)
        return 0;
    const uint8_t *p = buf + n_buf - n;
    return p[0] == 0xFF && p[1] == 0xFF && p[2] == 0xFD && p[3] == 0x00 && p[4] == last &&
           (p[5] | (p[6] << 8)) == n - 7;
}

PyDoc_STRVAR(transact_doc,
             "transact(fd, request, ids, length, fast, timeout_ms, then, byte_s, busy_until) "
             "-> (result, failed, data, errors, taken, received, events, sent, free_at)\n\n"
             "One Sync Read on a serial port's file descriptor, the GIL released throughout: "
             "write request, wait in poll() for the statuses until timeout_ms after it, read "
             "them as dynamixel-sdk does (sleeping while they cannot all be in yet: byte_s "
             "seconds a byte on the wire, the bus busy until busy_until with what the last "
             "call wrote), and write the packets of then as soon as the last "
             "status is whole, or after the read. received is every byte "
             "read, taken how many of them the SDK would have read; events are (kind, "
             "CLOCK_MONOTONIC s, bytes) in order, kind 'tx', 'rx' or 'timeout'; free_at, "
             "when the bus is free of what this call wrote (its next busy_until). "
             "An error of the port raises OSError.");

static PyObject *py_transact(PyObject *self, PyObject *args)
{
    int fd, fast;
    Py_buffer request, ids;
    Py_ssize_t length;
    double timeout_ms, byte_s, busy_until;
    PyObject *then;
    if (!PyArg_ParseTuple(args, "iy*y*npdO!dd", &fd, &request, &ids, &length, &fast,
                          &timeout_ms, &PyTuple_Type, &then, &byte_s, &busy_until))
        return NULL;
    PyObject *out = NULL;
    Py_ssize_t n_then = PyTuple_GET_SIZE(then);
    Py_buffer *packets = NULL;
    Py_ssize_t n_held = 0;
    int *sent = NULL;
    Events ev = {NULL, 0, 0};
    uint8_t *buf = NULL;
    Parsed o;
    int have_parsed = 0;
    if (check_ids(&ids) < 0)
        goto done;
    if (length < 0) {
        PyErr_SetString(PyExc_ValueError, "length must be >= 0");
        goto done;
    }
    packets = PyMem_Calloc((size_t)(n_then + 1), sizeof *packets);
    sent = PyMem_Calloc((size_t)(n_then + 1), sizeof *sent);
    if (packets == NULL || sent == NULL) {
        PyErr_NoMemory();
        goto done;
    }
    for (; n_held < n_then; n_held++)
        if (PyObject_GetBuffer(PyTuple_GET_ITEM(then, n_held), &packets[n_held],
                               PyBUF_SIMPLE) < 0)
            goto done;
    if (parsed_init(&o, ids.len, length) < 0) {
        PyErr_NoMemory();
        goto done;
    }
    have_parsed = 1;
    Py_ssize_t cap = 4096, received = 0, n_sent = 0;
    buf = malloc((size_t)cap);
    if (buf == NULL) {
        PyErr_NoMemory();
        goto done;
    }
    const uint8_t *id_bytes = ids.buf;
    Py_ssize_t n_ids = ids.len;
    int last = id_bytes[n_ids - 1];
    int os_error = 0, memory = 0, state = NEED_MORE;
    double free_at = 0; /* when the bus is free of what this call wrote */
    Stream s = {0};

    /* The statuses of a read are this long; they cannot be in before the request and
     * they have crossed the wire. */
    Py_ssize_t expected = fast ? 8 + n_ids * (length + 4) : n_ids * (11 + length);

    Py_BEGIN_ALLOW_THREADS
    os_error = write_all(fd, request.buf, request.len);
    double t = now_s(), deadline = t + timeout_ms * 1e-3;
    /* The bus may still carry the goals written after the last read (busy_until): the
     * request goes out behind them. */
    double earliest = (t > busy_until ? t : busy_until) + (double)(request.len + expected) * byte_s;
    if (os_error == 0 && add_event(&ev, 't', t, -1, 0, 0) < 0)
        memory = 1;
    int timed_out = 0;
    while (os_error == 0 && !memory) {
        /* Parsed from the start each time: the SDK's reading is a function of the bytes
         * received, and a read comes in a few chunks. */
        s = (Stream){buf, received, 0, timed_out, 0};
        state = parse_any(&s, id_bytes, n_ids, length, fast, &o);
        if (state != NEED_MORE) {
            memory = state < 0;
            break;
        }
        if (n_sent < n_then && !fast && tail_complete(buf, received, last, length)) {
            /* the bus is free: the goals go out now, while the statuses are decoded */
            os_error = send_then(fd, packets, n_then, &n_sent, sent, &ev, byte_s, &free_at,
                                 &memory);
            continue;
        }
        /* Sleep while the statuses cannot all be in yet, rather than wake for every
         * chunk an adapter hands over: each wake-up costs more than the parsing. */
        double now = now_s(), left = deadline - now;
        Py_ssize_t missing = expected - received;
        double until = received == 0 ? earliest : now + (double)missing * byte_s - USB_FLUSH_S;
        int wait_ms = left > 0 ? (int)ceil(left * 1e3) : 0;
        if (missing > 0 && until - now > SLEEP_MIN_S && until < deadline) {
            sleep_until(until);
            wait_ms = 0; /* then take what came, without waiting */
        }
        struct pollfd pfd = {fd, POLLIN, 0};
        int ready = poll(&pfd, 1, wait_ms);
        if (ready < 0) {
            if (errno != EINTR)
                os_error = errno;
            continue;
        }
        if (ready > 0) {
            if (received == cap) {
                Py_ssize_t bigger = cap * 2;
                uint8_t *p = bigger <= RX_CAP ? realloc(buf, (size_t)bigger) : NULL;
                if (p == NULL) { /* a flood of garbage: the rest is not kept */
                    timed_out = 1;
                    continue;
                }
                buf = p, cap = bigger;
            }
            ssize_t got = read(fd, buf + received, (size_t)(cap - received));
            if (got > 0) {
                if (add_event(&ev, 'r', now_s(), 0, received, got) < 0)
                    memory = 1;
                received += got;
                continue;
            }
            if (got == 0) {
                os_error = EIO; /* readable yet empty: the device is gone */
                continue;
            }
            if (errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR)
                os_error = errno;
            continue;
        }
        if (deadline - now_s() <= 0)
            timed_out = 1; /* a last look found nothing more: the deadline decides */
    }
    if (os_error == 0 && !memory && s.hit_timeout && add_event(&ev, 'o', now_s(), 0, 0, 0) < 0)
        memory = 1;
    /* What did not ride on the read goes out after it, as DxlBus.sync_read sends it. */
    if (free_at == 0)
        free_at = now_s(); /* no goals rode on the read: the bus is free once it is done */
    if (os_error == 0 && !memory)
        os_error = send_then(fd, packets, n_then, &n_sent, sent, &ev, byte_s, &free_at, &memory);
    Py_END_ALLOW_THREADS

    if (os_error != 0) {
        errno = os_error;
        PyErr_SetFromErrno(PyExc_OSError);
        goto done;
    }
    if (memory) {
        PyErr_NoMemory();
        goto done;
    }
    PyObject *res = parsed_result(&o, id_bytes, fast);
    if (res == NULL)
        goto done;
    PyObject *events = PyList_New(0), *sent_list = PyList_New(0);
    PyObject *all = PyBytes_FromStringAndSize((const char *)buf, received);
    int bad = events == NULL || sent_list == NULL || all == NULL;
    for (Py_ssize_t k = 0; !bad && k < ev.n; k++) {
        Event *e = &ev.ev[k];
        PyObject *item;
        if (e->kind == 't') {
            PyObject *packet =
                e->packet < 0 ? PyBytes_FromStringAndSize(request.buf, request.len)
                              : Py_NewRef(PyTuple_GET_ITEM(then, e->packet));
            item = packet == NULL ? NULL : Py_BuildValue("(sdN)", "tx", e->t, packet);
        } else if (e->kind == 'r') {
            item = Py_BuildValue("(sdy#)", "rx", e->t, (const char *)buf + e->off, e->len);
        } else {
            item = Py_BuildValue("(sdy)", "timeout", e->t, "");
        }
        bad = item == NULL || PyList_Append(events, item) < 0;
        Py_XDECREF(item);
    }
    for (Py_ssize_t k = 0; !bad && k < n_sent; k++) {
        PyObject *code = PyLong_FromLong(sent[k]);
        bad = code == NULL || PyList_Append(sent_list, code) < 0;
        Py_XDECREF(code);
    }
    if (!bad)
        out = Py_BuildValue("(OOOOnONNd)", PyTuple_GET_ITEM(res, 0), PyTuple_GET_ITEM(res, 1),
                            PyTuple_GET_ITEM(res, 2), PyTuple_GET_ITEM(res, 3), s.pos, all,
                            events, sent_list, free_at);
    else
        Py_XDECREF(events), Py_XDECREF(sent_list);
    Py_XDECREF(all);
    Py_DECREF(res);
done:
    if (have_parsed)
        parsed_free(&o);
    free(buf);
    free(ev.ev);
    for (Py_ssize_t k = 0; k < n_held; k++)
        PyBuffer_Release(&packets[k]);
    PyMem_Free(packets);
    PyMem_Free(sent);
    PyBuffer_Release(&request);
    PyBuffer_Release(&ids);
    return out;
}

static PyMethodDef methods[] = {
    {"crc16", py_crc16, METH_VARARGS, crc16_doc},
    {"packet", py_packet, METH_VARARGS, packet_doc},
    {"parse", py_parse, METH_VARARGS, parse_doc},
    {"transact", py_transact, METH_VARARGS, transact_doc},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {
    PyModuleDef_HEAD_INIT, "whexar.bus._wire",
    "The cycle's Dynamixel transactions in compiled code (see whexar.bus.wire).", -1, methods,
    NULL, NULL, NULL, NULL,
};

PyMODINIT_FUNC PyInit__wire(void)
{
    build_crc_table();
    PyObject *m = PyModule_Create(&module);
    if (m == NULL)
        return NULL;
    if (PyModule_AddIntConstant(m, "COMM_SUCCESS", COMM_SUCCESS) < 0 ||
        PyModule_AddIntConstant(m, "COMM_TX_FAIL", COMM_TX_FAIL) < 0 ||
        PyModule_AddIntConstant(m, "COMM_RX_TIMEOUT", COMM_RX_TIMEOUT) < 0 ||
        PyModule_AddIntConstant(m, "COMM_RX_CORRUPT", COMM_RX_CORRUPT) < 0) {
        Py_DECREF(m);
        return NULL;
    }
    return m;
}
