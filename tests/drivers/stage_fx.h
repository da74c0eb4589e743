/* stage_fx.h - the fixture of tests/drivers/test_stage*.c: a fake stage
 * (bin/specklab-fake-stage, --port 0 --ready-fd, READY read with a
 * bounded poll) and a drivers/stage handle on it, its fault registers
 * (>= 100) flipped over a raw libmodbus connection of their own, and the
 * fake stopped and reaped after the body, also when a CHECK failed.
 * Elapsed-time checks are upper bounds (configured bound + MARGIN_S),
 * never speed targets.  The fake is found at $SL_FAKE_STAGE, next to the
 * test binary's tree (../bin), or at bin/ (tests run from the repository
 * root).  Static functions: include once per test binary.
 */
#ifndef SL_STAGE_FX_H
#define SL_STAGE_FX_H

#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <poll.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include <modbus.h>

#include "../../mocks/fake-stage/fake_regs.h"
#include "stage.h"
#include "tcheck.h"

#define MARGIN_S 0.4     /* scheduling slack on top of every bound */
#define RESP_MS 300      /* response timeout of the test handles */
#define CALL_MS 1500     /* call bound of the test handles */

typedef struct fake {
    pid_t pid;
    int port;
    char rtu[64]; /* with --rtu: the pty it serves Modbus RTU on, else "" */
} fake;

typedef struct fixture {
    fake f;
    stage *s;
    stage_config cfg;
} fixture;

static inline double now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + ts.tv_nsec * 1e-9;
}

static inline void note(const char *what, double s)
{
    if (getenv("SL_VERBOSE"))
        fprintf(stderr, "  %s: %.0f ms\n", what, s * 1e3);
}

static inline const char *fake_path(char *buf, size_t n)
{
    const char *env = getenv("SL_FAKE_STAGE");
    char exe[PATH_MAX];
    if (env && *env)
        return env;
    ssize_t k = readlink("/proc/self/exe", exe, sizeof exe - 1);
    if (k > 0) {
        exe[k] = '\0';
        char *slash = strrchr(exe, '/');
        if (slash) { /* BUILD/tests/test_stage -> BUILD/bin/... */
            *slash = '\0';
            snprintf(buf, n, "%.3000s/../bin/specklab-fake-stage", exe);
            if (access(buf, X_OK) == 0)
                return buf;
        }
    }
    return "bin/specklab-fake-stage";
}

/* Bounded child reaping: SIGTERM, up to 2 s, then SIGKILL. */
static inline void reap(pid_t pid)
{
    if (pid <= 0)
        return;
    kill(pid, SIGTERM);
    for (int i = 0; i < 200; i++) {
        if (waitpid(pid, NULL, WNOHANG) == pid)
            return;
        struct timespec ts = {0, 10000000};
        nanosleep(&ts, NULL);
    }
    kill(pid, SIGKILL);
    waitpid(pid, NULL, 0);
}

/* Run argv (PATH searched) with a pipe on its fd `to` (1: stdout, or 3: a
 * ready fd) and stdout/stderr otherwise on /dev/null.  Returns the pipe's
 * read end, or -1; *pid = the child. */
static inline int spawn(const char *const *argv, int to, pid_t *pid)
{
    int fds[2];
    *pid = -1;
    if (pipe(fds) < 0)
        return -1;
    fcntl(fds[0], F_SETFD, FD_CLOEXEC);
    *pid = fork();
    if (*pid == 0) {
        int nul = open("/dev/null", O_WRONLY);
        dup2(nul, 1);
        dup2(nul, 2);
        if (fds[1] != to)
            dup2(fds[1], to); /* dup2 leaves the copy open across exec */
        execvp(argv[0], (char *const *)argv);
        _exit(127);
    }
    close(fds[1]);
    if (*pid < 0) {
        close(fds[0]);
        return -1;
    }
    return fds[0];
}

/* Read fd into buf (NUL-ended) until EOF, or a newline when `line`, for
 * at most 5 s.  Closes fd; returns the length. */
static inline int read_bounded(int fd, char *buf, size_t n, int line)
{
    double deadline = now_s() + 5.0;
    int len = 0;
    buf[0] = '\0';
    while (len < (int)n - 1 && !(line && strchr(buf, '\n'))) {
        struct pollfd p = {fd, POLLIN, 0};
        int ms = (int)((deadline - now_s()) * 1e3);
        if (ms <= 0 || poll(&p, 1, ms) <= 0)
            break;
        ssize_t r = read(fd, buf + len, n - 1 - (size_t)len);
        if (r <= 0)
            break;
        len += (int)r;
        buf[len] = '\0';
    }
    close(fd);
    return len;
}

static inline void fake_stop(fake *f)
{
    reap(f->pid);
    f->pid = -1;
}

/* Start the fake on port (0 = any) with extra arguments (NULL-ended) and
 * read its READY line within 5 s.  0, or -1 with the reason in why. */
static inline int fake_start(fake *f, int port, const char *const *extra,
                      char *why, size_t nwhy)
{
    char path[PATH_MAX], portarg[16], line[160];
    const char *argv[40] = {fake_path(path, sizeof path), "--port", portarg,
                            "--ready-fd", "3"};
    int n = 5;
    f->pid = -1;
    if (access(argv[0], X_OK) != 0) {
        snprintf(why, nwhy, "%.300s not built (run make): %.100s", argv[0],
                 strerror(errno));
        return -1;
    }
    snprintf(portarg, sizeof portarg, "%d", port);
    for (int i = 0; extra && extra[i] && n < 39; i++)
        argv[n++] = extra[i];
    int fd = spawn(argv, 3, &f->pid);
    if (fd < 0) {
        snprintf(why, nwhy, "cannot start %.300s: %.100s", argv[0],
                 strerror(errno));
        return -1;
    }
    read_bounded(fd, line, sizeof line, 1);
    if (sscanf(line, "READY port=%d", &f->port) != 1 || f->port <= 0) {
        snprintf(why, nwhy, "%.300s gave no READY line within 5 s (got "
                 "'%.60s')", argv[0], line);
        fake_stop(f);
        return -1;
    }
    const char *rtu = strstr(line, " rtu=");
    f->rtu[0] = '\0';
    if (rtu)
        sscanf(rtu + 5, "%63s", f->rtu);
    return 0;
}

/* The fault switches, over a connection of their own: write value to reg
 * (value >= 0) or read reg (value < 0).  The value read, 0, or -1. */
static inline int ctl(int port, int reg, int value)
{
    modbus_t *c = modbus_new_tcp("127.0.0.1", port);
    uint16_t v = (uint16_t)value;
    int rc = -1;
    if (!c)
        return -1;
    modbus_set_response_timeout(c, 1, 0);
    if (modbus_connect(c) == 0) {
        if (value >= 0)
            rc = modbus_write_register(c, reg, v) == 1 ? 0 : -1;
        else
            rc = modbus_read_registers(c, reg, 1, &v) == 1 ? v : -1;
        modbus_close(c);
    }
    modbus_free(c);
    return rc;
}

static inline void test_config(stage_config *cfg, int port)
{
    stage_config_defaults(cfg);
    cfg->port = port;
    cfg->response_timeout_ms = RESP_MS;
    cfg->call_timeout_ms = CALL_MS;
    cfg->move_timeout_ms = 3000;
    cfg->backoff_min_ms = 20;
    cfg->backoff_max_ms = 200;
}

static inline int fixture_up(tc *t, fixture *fx, const char *const *args)
{
    char why[512];
    sl_err e = {0};
    memset(fx, 0, sizeof *fx);
    fx->f.pid = -1;
    if (fake_start(&fx->f, 0, args, why, sizeof why) < 0) {
        tc_note(t, 0, __FILE__, __LINE__, "fake_start", "%s", why);
        return -1;
    }
    test_config(&fx->cfg, fx->f.port);
    int rc = stage_new(&fx->s, &fx->cfg, &e);
    if (rc != SL_OK) {
        tc_note(t, 0, __FILE__, __LINE__, "stage_new", "%s", e.msg);
        return -1;
    }
    return 0;
}

static inline void fixture_down(fixture *fx)
{
    stage_free(fx->s);
    fake_stop(&fx->f);
}

/* A test body gets a running fake and a handle; the fake is reaped after
 * the body returns, whether its CHECKs passed or not. */
#define STAGE_TEST(name, ...)                                                 \
    static void name##_body(tc *t, fixture *fx);                              \
    TEST(name)                                                                \
    {                                                                         \
        static const char *const args[] = {__VA_ARGS__ NULL};                 \
        fixture fx;                                                           \
        if (fixture_up(t, &fx, args) == 0)                                    \
            name##_body(t, &fx);                                              \
        fixture_down(&fx);                                                    \
    }                                                                         \
    static void name##_body(tc *t, fixture *fx)

#define HAS(s, sub) (strstr((s), (sub)) != NULL)

#endif
