/* test_stage_rtu_daemon.c - specklabd's [stage] backend=rtu (device,
 * baud, parity, unit) against bin/specklab-fake-stage --rtu on a
 * pseudo-terminal (stage_fx.h starts it): the daemon's settings reach the
 * line, its device query reads the wheels through the pty, a mismatched
 * parity is a named "no reply" with what to check (stage_probe.h), an
 * unknown one stops the daemon.
 * specklabd and specklab are taken from the fake's directory.
 */
#include "stage_fx.h"

typedef struct dstage {
    char dir[64], bin[PATH_MAX], tty[96], conf[96], log[96], sock[96];
    pid_t pid;
} dstage;

/* Write the configuration with parity (and the fake's unit 7), start
 * specklabd on it and wait up to 10 s for READY.  0 ready, 1 it exited
 * (its log says why), -1 it could not start. */
static int daemon_up(dstage *d, const char *parity)
{
    char exe[PATH_MAX + 16];
    FILE *f = fopen(d->conf, "w");
    if (!f)
        return -1;
    fprintf(f, "[stage]\nbackend=rtu\ndevice=%s\nbaud=19200\nparity=%s\nunit=7\n"
            "response_timeout_ms=200\ncall_timeout_ms=600\n"
            "[paths]\ndata_dir=%s\n[daemon]\nsocket=%s\n", d->tty, parity,
            d->dir, d->sock);
    fclose(f);
    snprintf(exe, sizeof exe, "%s/specklabd", d->bin);
    unlink(d->log); /* the last daemon's READY is not this one's */
    d->pid = fork();
    if (d->pid == 0) {
        int fd = open(d->log, O_WRONLY | O_CREAT | O_TRUNC, 0644);
        dup2(fd, 1);
        dup2(fd, 2);
        execl(exe, exe, "--foreground", "--config", d->conf, (char *)NULL);
        _exit(127);
    }
    if (d->pid < 0)
        return -1;
    for (double t0 = now_s(); now_s() - t0 < 10;) {
        char buf[4096] = "";
        FILE *l = fopen(d->log, "r");
        if (l) {
            size_t n = fread(buf, 1, sizeof buf - 1, l);
            buf[n] = '\0';
            fclose(l);
        }
        if (strstr(buf, "READY socket="))
            return 0;
        if (waitpid(d->pid, NULL, WNOHANG) == d->pid) {
            d->pid = -1;
            return 1;
        }
        struct timespec ts = {0, 20000000};
        nanosleep(&ts, NULL);
    }
    return -1;
}

/* `specklab daemon status` into out (bounded: read_bounded's 5 s). */
static int daemon_status(const dstage *d, char *out, size_t n)
{
    char exe[PATH_MAX + 16];
    pid_t pid;
    int status = -1;
    snprintf(exe, sizeof exe, "%s/specklab", d->bin);
    const char *argv[] = {exe, "daemon", "status", "--socket", d->sock, NULL};
    int fd = spawn(argv, 1, &pid);
    out[0] = '\0';
    if (fd < 0)
        return -1;
    read_bounded(fd, out, n, 0);
    kill(pid, SIGKILL);
    waitpid(pid, &status, 0);
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

static void read_file(const char *path, char *out, size_t n)
{
    FILE *f = fopen(path, "r");
    size_t k = f ? fread(out, 1, n - 1, f) : 0;
    out[k] = '\0';
    if (f)
        fclose(f);
}

/* The daemon's [stage] reaches the line: the fake answers unit 7, parity
 * O, 19200 baud.  parity=O: the stage is connected and its wheels read;
 * parity=E: no reply, named; parity=X: specklabd refuses to start. */
TEST(rtu_daemon_config)
{
    dstage d = {.pid = -1};
    fake f = {-1, 0, ""};
    char why[512], out[8192], log[4096] = "", path[PATH_MAX];
    int up[3] = {-1, -1, -1}, st[2] = {-1, -1};
    char outs[2][8192] = {"", ""};
    snprintf(d.dir, sizeof d.dir, "/tmp/sl-rtud-XXXXXX");
    CHECK(mkdtemp(d.dir) != NULL, "mkdtemp: %s", strerror(errno));
    snprintf(d.bin, sizeof d.bin, "%s", fake_path(path, sizeof path));
    *strrchr(d.bin, '/') = '\0';
    snprintf(d.tty, sizeof d.tty, "%s/ttySTAGE", d.dir);
    snprintf(d.conf, sizeof d.conf, "%s/specklabd.conf", d.dir);
    snprintf(d.log, sizeof d.log, "%s/specklabd.log", d.dir);
    snprintf(d.sock, sizeof d.sock, "%s/specklabd.sock", d.dir);
    const char *const args[] = {"--rtu-link", d.tty, "--unit", "7", "--parity", "O",
                                NULL};
    int fake_ok = fake_start(&f, 0, args, why, sizeof why) == 0;
    static const char *const parity[] = {"O", "E", "X"};
    for (int i = 0; i < 3 && fake_ok; i++) {
        up[i] = daemon_up(&d, parity[i]);
        if (up[i] == 0 && i < 2)
            st[i] = daemon_status(&d, outs[i], sizeof outs[i]);
        if (i == 2)
            read_file(d.log, log, sizeof log);
        reap(d.pid);
        d.pid = -1;
    }
    fake_stop(&f);
    char rm[160];
    snprintf(rm, sizeof rm, "rm -rf '%s'", d.dir);
    if (system(rm) != 0)
        fprintf(stderr, "could not remove %s\n", d.dir);
    CHECK(fake_ok, "%s", why);
    char want[160];
    snprintf(want, sizeof want, "stage:       %s (connected)", d.tty);
    memcpy(out, outs[0], sizeof out);
    CHECK(up[0] == 0 && st[0] == 0 && HAS(out, want) &&
          HAS(out, "wheel screen  no slot of 6") && HAS(out, "wheel mask    no slot of 6"),
          "parity=O: start %d, status %d:\n%s", up[0], st[0], out);
    snprintf(want, sizeof want, "stage:       %s (NOT CONNECTED)", d.tty);
    memcpy(out, outs[1], sizeof out);
    CHECK(up[1] == 0 && st[1] == 0 && HAS(out, want) &&
          HAS(out, "no reply at 19200 baud, parity E (even), unit 7") &&
          HAS(out, "fix: check the baud rate and parity") && HAS(out, "specklab devices --stage"),
          "parity=E: start %d, status %d:\n%s", up[1], st[1], out);
    CHECK(up[2] == 1 && HAS(log, "[stage] parity = 'X': expected N (none), E (even) "
          "or O (odd)"), "parity=X: start %d:\n%s", up[2], log);
}

TC_MAIN(TC_CASE(rtu_daemon_config))
