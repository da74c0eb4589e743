/* fuzz_stage.c - libFuzzer target: the stage driver's reply handling
 * (drivers/stage.c, drivers/stage_modbus.c and libmodbus's reply parsing
 * under them), against a Modbus TCP peer whose answers the input chooses.
 *
 * Why a peer on loopback and not a pure decoding function: the driver's
 * only pure step, decode() of six registers into stage_wheel_status, is a
 * handful of shifts that cannot fail.  What can go wrong with a hostile or
 * broken stage is the rest: libmodbus's checks of the reply frame, the
 * identity handshake, busy retries, exceptions turned into messages
 * (refused() reads the wheel again to explain), reconnection after
 * garbage, and stage_wait's polling.  So a server thread in this process
 * listens on 127.0.0.1 (ephemeral port) and answers each request from the
 * input's script; short timeouts (20 ms reply, 60 ms call) keep an input
 * well under a second.
 *
 * Input = [k][k op bytes][script].  k = 1 + byte % 6 driver calls, each
 * op byte picking a call and its wheel / slot.  The script is a sequence
 * of reply records, one per request the server receives, in order:
 *   m % 8 = 0..2  answer from the register model (below)
 *           3     poke: [reg][hi][lo] sets model register reg % 64, then
 *                 answer from the model
 *           4     exception: [code] -> function | 0x80, code
 *           5     PDU: [len][len bytes] after a correct MBAP header
 *                 (transaction id, unit echoed): fuzzes the PDU checks
 *           6     raw: [len][len bytes] sent as they are
 *           7     [c]: c odd = close the connection (RST), even = no
 *                 reply (the driver's timeout path; costs 20 ms)
 * Once the script is used up the server answers from the model, so every
 * input ends quickly.  The model is a healthy two-wheel stage (magic, map
 * version 1, 6 slots, homed, in position) in which HOME / MOVE complete at
 * once, so a call succeeds unless the script says otherwise.
 * Contract checks abort (a finding): a failed call leaves a message that
 * starts "stage 127.0.0.1:PORT: "; a successful stage_info reports the
 * magic, version and wheel count the driver promises to verify; a
 * successful stage_move was to a slot inside the wheel's reported range.
 */
#define _GNU_SOURCE
#include <arpa/inet.h>
#include <errno.h>
#include <netinet/in.h>
#include <poll.h>
#include <pthread.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <unistd.h>

#include "stage.h"

#define RESP_MS 20
#define CALL_MS 60
#define WAIT_MS 40
#define NREG 64

int LLVMFuzzerInitialize(int *argc, char ***argv);
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

/* Shared by the fuzzer thread and the server thread, under mu.  The
 * fuzzer installs a script, runs the calls, frees the stage (closing its
 * socket) and waits for the server to be back in accept(). */
typedef struct peer {
    pthread_mutex_t mu;
    pthread_cond_t cv;
    int listen_fd, port;
    const uint8_t *script;
    size_t len, pos;
    uint16_t reg[NREG];
    int busy;        /* server is inside a connection */
} peer;

static peer P = {PTHREAD_MUTEX_INITIALIZER, PTHREAD_COND_INITIALIZER,
                 -1, 0, NULL, 0, 0, {0}, 0};

static void model_reset(uint16_t *r)
{
    memset(r, 0, NREG * sizeof *r);
    r[STAGE_REG_MAGIC] = STAGE_MAGIC;
    r[STAGE_REG_VERSION] = STAGE_MAP_VERSION;
    r[STAGE_REG_NWHEELS] = STAGE_NWHEELS;
    for (int w = 0; w < STAGE_NWHEELS; w++) {
        uint16_t *b = r + STAGE_REG_WHEEL_BASE(w);
        b[STAGE_WREG_SLOTS] = 6;
        b[STAGE_WREG_STATUS] = STAGE_ST_INPOS | STAGE_ST_HOMED;
        b[STAGE_WREG_MOVE_MS] = 100;
    }
}

/* A command just landed in registers 3..4: complete it at once. */
static void model_command(uint16_t *r)
{
    unsigned cmd = r[STAGE_REG_COMMAND], wh = r[STAGE_REG_CMD_WHEEL];
    for (unsigned w = 0; w < STAGE_NWHEELS; w++) {
        if (wh != STAGE_WHEEL_ALL && wh != w)
            continue;
        uint16_t *b = r + STAGE_REG_WHEEL_BASE(w);
        if (cmd == STAGE_CMD_HOME || cmd == STAGE_CMD_MOVE) {
            b[STAGE_WREG_POSITION] =
                cmd == STAGE_CMD_HOME ? 0 : b[STAGE_WREG_TARGET];
            b[STAGE_WREG_STATUS] = STAGE_ST_INPOS | STAGE_ST_HOMED;
        } else if (cmd == STAGE_CMD_RESET) {
            b[STAGE_WREG_FAULT] = 0;
            b[STAGE_WREG_STATUS] &= (uint16_t)~STAGE_ST_FAULT;
        }
    }
    r[STAGE_REG_COMMAND] = 0;
}

static int script_byte(peer *p)
{
    return p->pos < p->len ? p->script[p->pos++] : -1;
}

/* Read exactly n bytes within 200 ms per chunk; 0 on success. */
static int read_full(int fd, uint8_t *buf, size_t n)
{
    for (size_t got = 0; got < n;) {
        struct pollfd pf = {fd, POLLIN, 0};
        if (poll(&pf, 1, 200) <= 0)
            return -1;
        ssize_t k = recv(fd, buf + got, n - got, 0);
        if (k <= 0)
            return -1;
        got += (size_t)k;
    }
    return 0;
}

static void send_all(int fd, const uint8_t *buf, size_t n)
{
    while (n > 0) {
        ssize_t k = send(fd, buf, n, MSG_NOSIGNAL);
        if (k <= 0)
            return;
        buf += k;
        n -= (size_t)k;
    }
}

/* The model's answer to PDU q[0..n) into out (after the MBAP header);
 * returns the PDU length. */
static size_t model_answer(uint16_t *r, const uint8_t *q, size_t n,
                           uint8_t *out)
{
    unsigned fc = n ? q[0] : 0;
    unsigned addr = n >= 3 ? (unsigned)(q[1] << 8 | q[2]) : 0;
    unsigned cnt = n >= 5 ? (unsigned)(q[3] << 8 | q[4]) : 0;
    out[0] = (uint8_t)fc;
    if (fc == 0x03 && n >= 5 && cnt >= 1 && cnt <= 125 && addr + cnt <= NREG) {
        out[1] = (uint8_t)(2 * cnt);
        for (unsigned i = 0; i < cnt; i++) {
            out[2 + 2 * i] = (uint8_t)(r[addr + i] >> 8);
            out[3 + 2 * i] = (uint8_t)r[addr + i];
        }
        return 2 + 2 * cnt;
    }
    if (fc == 0x06 && n >= 5 && addr < NREG) {
        r[addr] = (uint16_t)cnt; /* the value */
        memcpy(out, q, 5);
        if (addr == STAGE_REG_COMMAND)
            model_command(r);
        return 5;
    }
    if (fc == 0x10 && n >= 6 && cnt >= 1 && addr + cnt <= NREG &&
        n >= 6 + 2 * (size_t)cnt) {
        for (unsigned i = 0; i < cnt; i++)
            r[addr + i] = (uint16_t)(q[6 + 2 * i] << 8 | q[7 + 2 * i]);
        memcpy(out, q, 5);
        if (addr <= STAGE_REG_COMMAND && STAGE_REG_COMMAND < addr + cnt)
            model_command(r);
        return 5;
    }
    out[0] = (uint8_t)(fc | 0x80);
    out[1] = fc == 0x03 || fc == 0x06 || fc == 0x10 ? 0x02 : 0x01;
    return 2;
}

/* One request on fd, answered as the script says; -1 ends the connection. */
static int serve_one(peer *p, int fd)
{
    uint8_t hdr[7], pdu[260], out[300];
    if (read_full(fd, hdr, 7))
        return -1;
    size_t n = (size_t)(hdr[4] << 8 | hdr[5]);
    if (n < 1 || n - 1 > sizeof pdu || read_full(fd, pdu, n - 1))
        return -1;
    n -= 1;
    pthread_mutex_lock(&p->mu);
    int m = script_byte(p), a, len = 0;
    size_t plen = 0;
    int action = m < 0 ? 0 : m % 8, close_it = 0, silent = 0, raw = 0;
    switch (action) {
    case 3:
        a = script_byte(p);
        if (a >= 0) {
            int hi = script_byte(p), lo = script_byte(p);
            p->reg[a % NREG] = (uint16_t)((hi < 0 ? 0 : hi) << 8 |
                                          (lo < 0 ? 0 : lo));
        }
        plen = model_answer(p->reg, pdu, n, out + 7);
        break;
    case 4:
        a = script_byte(p);
        out[7] = (uint8_t)((n ? pdu[0] : 0) | 0x80);
        out[8] = (uint8_t)(a < 0 ? 0x06 : a);
        plen = 2;
        break;
    case 5:
    case 6:
        len = script_byte(p);
        len = len < 0 ? 0 : len;
        for (int i = 0; i < len; i++) {
            int b = script_byte(p);
            out[(action == 5 ? 7 : 0) + i] = (uint8_t)(b < 0 ? 0 : b);
        }
        plen = (size_t)len;
        raw = action == 6;
        break;
    case 7:
        a = script_byte(p);
        close_it = a < 0 || (a & 1);
        silent = !close_it;
        break;
    default:
        plen = model_answer(p->reg, pdu, n, out + 7);
        break;
    }
    pthread_mutex_unlock(&p->mu);
    if (close_it)
        return -1;
    if (silent)
        return 0;
    if (raw) {
        send_all(fd, out, plen);
        return 0;
    }
    memcpy(out, hdr, 4); /* transaction and protocol ids */
    out[4] = (uint8_t)((plen + 1) >> 8);
    out[5] = (uint8_t)(plen + 1);
    out[6] = hdr[6]; /* unit */
    send_all(fd, out, 7 + plen);
    return 0;
}

static void *server(void *arg)
{
    peer *p = arg;
    for (;;) {
        int fd = accept(p->listen_fd, NULL, NULL);
        if (fd < 0)
            continue;
        pthread_mutex_lock(&p->mu);
        p->busy = 1;
        pthread_mutex_unlock(&p->mu);
        while (serve_one(p, fd) == 0)
            ;
        /* RST instead of FIN: no TIME_WAIT pile-up over millions of runs */
        struct linger lg = {1, 0};
        setsockopt(fd, SOL_SOCKET, SO_LINGER, &lg, sizeof lg);
        close(fd);
        pthread_mutex_lock(&p->mu);
        p->busy = 0;
        pthread_cond_broadcast(&p->cv);
        pthread_mutex_unlock(&p->mu);
    }
    return NULL;
}

int LLVMFuzzerInitialize(int *argc, char ***argv)
{
    (void)argc;
    (void)argv;
    struct sockaddr_in a = {0};
    socklen_t al = sizeof a;
    pthread_t th;
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    P.listen_fd = socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    if (P.listen_fd < 0 || bind(P.listen_fd, (struct sockaddr *)&a, al) ||
        listen(P.listen_fd, 8) ||
        getsockname(P.listen_fd, (struct sockaddr *)&a, &al) ||
        pthread_create(&th, NULL, server, &P)) {
        perror("fuzz_stage: loopback server");
        abort();
    }
    pthread_detach(th);
    P.port = ntohs(a.sin_port);
    return 0;
}

static void require(int cond, const char *what, const char *msg)
{
    if (!cond) {
        fprintf(stderr, "fuzz_stage: contract broken: %s (%s)\n", what, msg);
        abort();
    }
}

/* One driver call chosen by op; checks what its result promises. */
static void call(stage *s, unsigned op, const char *prefix)
{
    int wheel = (op >> 3) & 1, any = (op >> 3) % 3, rc;
    int wheel_all = any == 2 ? STAGE_WHEEL_ALL : any;
    int slot = (int)(op >> 4) - 2; /* -2..13: below, inside, past 6 */
    stage_ident id;
    stage_wheel_status st;
    switch (op % 8) {
    case 0:
        rc = stage_info(s, &id);
        if (rc == SL_OK)
            require(id.magic == STAGE_MAGIC && id.version >= 1 &&
                        id.version <= STAGE_MAP_VERSION &&
                        id.nwheels == STAGE_NWHEELS,
                    "stage_info", "identity the handshake should refuse");
        break;
    case 1:
        rc = stage_status(s, wheel, &st);
        if (rc == SL_OK)
            require(st.wheel == wheel && st.fault_text != NULL &&
                        st.busy == !!(st.status & STAGE_ST_BUSY),
                    "stage_status", "decoded status");
        break;
    case 2: rc = stage_home(s, wheel_all); break;
    case 3:
        rc = stage_move(s, wheel, slot);
        if (rc == SL_OK) {
            rc = stage_info(s, &id);
            require(rc != SL_OK || (slot >= 0 && slot < id.slots[wheel]),
                    "stage_move", "accepted a slot out of range");
            rc = SL_OK;
        }
        break;
    case 4: rc = stage_stop(s, wheel_all); break;
    case 5: rc = stage_reset(s, wheel_all); break;
    case 6: rc = stage_wait(s, wheel_all, WAIT_MS); break;
    default: rc = stage_move_wait(s, wheel, slot, WAIT_MS); break;
    }
    if (rc != SL_OK) {
        const char *msg = stage_errmsg(s);
        require(rc < 0 && rc >= SL_EEND, "call", "status outside SL_E*");
        require(strncmp(msg, prefix, strlen(prefix)) == 0 &&
                    strlen(msg) > strlen(prefix),
                "call", msg);
    }
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size < 2)
        return 0;
    size_t k = 1 + data[0] % 6;
    if (size < 1 + k)
        return 0;
    stage_config cfg;
    stage_config_defaults(&cfg);
    cfg.port = P.port;
    cfg.response_timeout_ms = RESP_MS;
    cfg.call_timeout_ms = CALL_MS;
    cfg.move_timeout_ms = WAIT_MS;
    cfg.backoff_min_ms = 1;
    cfg.backoff_max_ms = 4;
    pthread_mutex_lock(&P.mu);
    P.script = data + 1 + k;
    P.len = size - 1 - k;
    P.pos = 0;
    model_reset(P.reg);
    pthread_mutex_unlock(&P.mu);

    char prefix[64];
    snprintf(prefix, sizeof prefix, "stage 127.0.0.1:%d: ", P.port);
    stage *s = NULL;
    sl_err e = {0};
    if (stage_new(&s, &cfg, &e) != SL_OK) {
        fprintf(stderr, "fuzz_stage: stage_new: %s\n", e.msg);
        abort();
    }
    for (size_t i = 0; i < k; i++)
        call(s, data[1 + i], prefix);
    stage_free(s);

    /* The server must be done with this input's connection before the
     * next input's script is installed (it notices the close at once). */
    pthread_mutex_lock(&P.mu);
    while (P.busy)
        pthread_cond_wait(&P.cv, &P.mu);
    P.script = NULL;
    P.len = P.pos = 0;
    pthread_mutex_unlock(&P.mu);
    return 0;
}
