/* proc_fx.h - test fixtures for programs under test: start them with
 * stdout on a pipe, wait for their READY line with a deadline, stop and
 * reap them; run a test body in a forked child inside a private network
 * namespace (GVCP's port 3956 is fixed, so each camera needs its own
 * loopback).  Used by the driver, integration and soak tests.
 *
 * Namespaces: the child unshares CLONE_NEWNET (with CLONE_NEWUSER when not
 * root) and brings its loopback up; everything it starts shares that
 * loopback and dies with it (PR_SET_PDEATHSIG).  The parent reads the
 * child's verdict through a pipe with a deadline.  Nothing sleeps as
 * synchronisation: fx_nap_ms only paces bounded polls.
 *
 * Static inline functions: include from test sources only.
 */
#ifndef SL_PROC_FX_H
#define SL_PROC_FX_H

#ifndef _GNU_SOURCE
#define _GNU_SOURCE
#endif
#include <errno.h>
#include <fcntl.h>
#include <libgen.h>
#include <limits.h>
#include <net/if.h>
#include <poll.h>
#include <sched.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/ioctl.h>
#include <sys/prctl.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "tcheck.h"

static inline double fx_now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec + ts.tv_nsec * 1e-9;
}

static inline void fx_nap_ms(int ms)   /* between polls of a bounded wait only */
{
    struct timespec ts = {ms / 1000, (ms % 1000) * 1000000L};
    nanosleep(&ts, NULL);
}

/* ---- namespaces ------------------------------------------------------------ */

static inline int fx_write_file(const char *path, const char *text)
{
    int fd = open(path, O_WRONLY);
    if (fd < 0)
        return -1;
    ssize_t w = write(fd, text, strlen(text));
    close(fd);
    return w == (ssize_t)strlen(text) ? 0 : -1;
}

static inline int fx_enter_netns(char *why, size_t n)
{
    uid_t uid = getuid();
    gid_t gid = getgid();
    if (unshare(CLONE_NEWNET) != 0) {
        char map[64];
        if (unshare(CLONE_NEWUSER | CLONE_NEWNET) != 0) {
            snprintf(why, n, "unshare: %s", strerror(errno));
            return -1;
        }
        fx_write_file("/proc/self/setgroups", "deny");
        snprintf(map, sizeof map, "0 %d 1", (int)uid);
        fx_write_file("/proc/self/uid_map", map);
        snprintf(map, sizeof map, "0 %d 1", (int)gid);
        fx_write_file("/proc/self/gid_map", map);
    }
    struct ifreq ifr = {0};
    int s = socket(AF_INET, SOCK_DGRAM, 0);
    snprintf(ifr.ifr_name, sizeof ifr.ifr_name, "lo");
    int rc = s < 0 || ioctl(s, SIOCGIFFLAGS, &ifr) != 0 ? -1 : 0;
    ifr.ifr_flags |= IFF_UP | IFF_RUNNING;
    if (rc == 0 && ioctl(s, SIOCSIFFLAGS, &ifr) != 0)
        rc = -1;
    if (s >= 0)
        close(s);
    if (rc)
        snprintf(why, n, "bringing lo up: %s", strerror(errno));
    return rc;
}

/* Run body in a forked child (in a fresh network namespace when netns);
 * its verdict comes back through a pipe within limit_s.  Without
 * namespaces the test is skipped (the fixed GVCP port would collide with
 * other cameras). */
static inline void fx_run_child(tc *t, void (*body)(tc *), int limit_s, int netns)
{
    int p[2];
    CHECK(pipe(p) == 0, "pipe: %s", strerror(errno));
    fflush(stdout);
    fflush(stderr);
    pid_t pid = fork();
    CHECK(pid >= 0, "fork: %s", strerror(errno));
    if (pid == 0) {
        tc ct = {0};
        char why[256];
        close(p[0]);
        if (netns && fx_enter_netns(why, sizeof why) != 0)
            tc_note(&ct, 1, __FILE__, __LINE__, "", "no private network namespace: %s", why);
        else
            body(&ct);
        fflush(stdout);
        ssize_t w = write(p[1], &ct, sizeof ct);
        exit(w == (ssize_t)sizeof ct ? 0 : 3);
    }
    close(p[1]);
    tc ct;
    size_t got = 0;
    double end = fx_now() + limit_s;
    while (got < sizeof ct && fx_now() < end) {
        struct pollfd pf = {p[0], POLLIN, 0};
        if (poll(&pf, 1, 200) <= 0)
            continue;
        ssize_t r = read(p[0], (char *)&ct + got, sizeof ct - got);
        if (r <= 0)
            break;
        got += (size_t)r;
    }
    close(p[0]);
    if (got < sizeof ct)
        kill(pid, SIGKILL);
    int st = 0;
    waitpid(pid, &st, 0);
    CHECK(got == sizeof ct, "test child gave no verdict within %d s (%s %d)", limit_s,
          WIFSIGNALED(st) ? "signal" : "exit", WIFSIGNALED(st) ? WTERMSIG(st) : WEXITSTATUS(st));
    *t = ct;
    if (!t->failed && !(WIFEXITED(st) && WEXITSTATUS(st) == 0)) {
        t->failed = 1;
        snprintf(t->msg, sizeof t->msg, "test child %s %d after its verdict (a leak?)",
                 WIFSIGNALED(st) ? "died of signal" : "exited",
                 WIFSIGNALED(st) ? WTERMSIG(st) : WEXITSTATUS(st));
    }
}

static inline void fx_in_netns(tc *t, void (*body)(tc *), int limit_s)
{
    fx_run_child(t, body, limit_s, 1);
}

/* Run body in a forked child (a fresh Aravis, libusb and GLib state for
 * each test), with the same verdict pipe and deadline. */
static inline void fx_in_child(tc *t, void (*body)(tc *), int limit_s)
{
    fx_run_child(t, body, limit_s, 0);
}

/* ---- processes --------------------------------------------------------------- */

static inline void fx_bin(char *out, size_t n, const char *name)
{
    const char *env = getenv("SL_BIN_DIR");
    if (!env || !*env)
        env = getenv("SL_BIN");
    if (env && *env) {
        snprintf(out, n, "%s/%s", env, name);
        return;
    }
    char exe[PATH_MAX] = "";
    ssize_t len = readlink("/proc/self/exe", exe, sizeof exe - 1);
    exe[len > 0 ? len : 0] = 0;
    /* BUILD/tests/test_x -> BUILD/bin (make asan), else ./bin */
    snprintf(out, n, "%s/bin/%s", dirname(dirname(exe)), name);
    if (access(out, X_OK) != 0)
        snprintf(out, n, "bin/%s", name);
}

#define FX_STDERR ((const char *)1)

typedef struct fx_proc {
    pid_t pid;
    int out;      /* its stdout, -1 when none */
} fx_proc;

/* Start argv[0] with stdout on a pipe and stderr appended to errlog
 * (NULL: /dev/null; FX_STDERR: this process's stderr).  pre(arg) runs in the child before exec. */
static inline int fx_spawn(fx_proc *p, char *const argv[], const char *errlog,
                    void (*pre)(void *), void *arg)
{
    int fd[2];
    p->pid = -1;
    p->out = -1;
    if (pipe2(fd, O_CLOEXEC) != 0)
        return -1;
    fflush(stdout);
    fflush(stderr);
    pid_t pid = fork();
    if (pid < 0)
        return -1;
    if (pid == 0) {
        prctl(PR_SET_PDEATHSIG, SIGKILL);
        dup2(fd[1], 1);
        if (errlog != FX_STDERR) {
            int e = open(errlog ? errlog : "/dev/null", O_WRONLY | O_CREAT | O_APPEND, 0644);
            if (e >= 0)
                dup2(e, 2);
        }
        if (pre)
            pre(arg);
        execv(argv[0], argv);
        _exit(127);
    }
    close(fd[1]);
    p->pid = pid;
    p->out = fd[0];
    return 0;
}

/* Read stdout until a line starting with READY (copied to line). */
static inline int fx_wait_ready(fx_proc *p, char *line, size_t n, double limit_s)
{
    size_t len = 0;
    double end = fx_now() + limit_s;
    while (fx_now() < end) {
        struct pollfd pf = {p->out, POLLIN, 0};
        if (poll(&pf, 1, 100) <= 0)
            continue;
        if (len + 1 >= n || read(p->out, line + len, 1) != 1)
            return -1;   /* exited before READY */
        if (line[len] == '\n') {
            line[len] = 0;
            if (strncmp(line, "READY", 5) == 0)
                return 0;
            len = 0;
        } else {
            len++;
        }
    }
    return -1;
}

/* Signal and reap within limit_s (then SIGKILL); the exit status or -1. */
static inline int fx_stop(fx_proc *p, int sig, double limit_s)
{
    int st = 0, rc = -1;
    if (p->pid <= 0)
        return -1;
    kill(p->pid, sig);
    double end = fx_now() + limit_s;
    pid_t w;
    while ((w = waitpid(p->pid, &st, WNOHANG)) == 0 && fx_now() < end)
        fx_nap_ms(10);
    if (w == 0) {
        kill(p->pid, SIGKILL);
        waitpid(p->pid, &st, 0);
    } else if (w > 0 && WIFEXITED(st)) {
        rc = WEXITSTATUS(st);
    }
    if (p->out >= 0)
        close(p->out);
    p->pid = -1;
    p->out = -1;
    return rc;
}

/* Run argv to its end within limit_s (then SIGKILL), stderr to errlog and
 * pre(arg) as fx_spawn; its stdout in out (NUL-ended, cut at n).  The exit
 * status, -1 when it could not start or was killed. */
static inline int fx_run(char *const argv[], const char *errlog, void (*pre)(void *), void *arg,
                         char *out, size_t n, double limit_s)
{
    fx_proc p;
    size_t len = 0;
    out[0] = 0;
    if (fx_spawn(&p, argv, errlog, pre, arg) != 0)
        return -1;
    double end = fx_now() + limit_s;
    for (;;) {
        struct pollfd pf = {p.out, POLLIN, 0};
        if (fx_now() >= end || (poll(&pf, 1, 100) > 0 &&
                                (len + 1 >= n || read(p.out, out + len, 1) != 1)))
            break;   /* the deadline, EOF or a full buffer */
        if (pf.revents & POLLIN)
            out[++len] = 0;
    }
    int st = fx_stop(&p, fx_now() < end ? 0 : SIGKILL, fx_now() < end ? end - fx_now() : 1);
    return st;
}

static inline int fx_alive(const fx_proc *p)
{
    int st;
    return p->pid > 0 && waitpid(p->pid, &st, WNOHANG) == 0;
}

#endif
