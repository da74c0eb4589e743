/* u3v_fx.h - bin/specklab-fake-u3v for tests: start it with a pipe on
 * its stdin (unplug / plug commands), wait for its READY line, and point
 * this process's umockdev preload at its testbed.  The process using the
 * camera must run under the preload (preload_fx.h); programs it starts
 * inherit $LD_PRELOAD and $UMOCKDEV_DIR.
 */
#ifndef SL_TEST_U3V_FX_H
#define SL_TEST_U3V_FX_H

#include <fcntl.h>
#include <limits.h>
#include <poll.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "proc_fx.h"

#define FX_U3V_SERIAL "SPECKTEST"
#define FX_U3V_ID "Specklab-" FX_U3V_SERIAL   /* Aravis's vendor-serial id */

typedef struct fx_u3v {
    fx_proc p;
    int in;                      /* its stdin, -1 when none */
    char dir[PATH_MAX], node[64];
} fx_u3v;

static inline void fx_u3v_stdin(void *arg)
{
    dup2(*(int *)arg, 0);
}

/* One line of its stdout within limit_s (without the newline). */
static inline int fx_u3v_line(fx_u3v *u, char *line, size_t n, double limit_s)
{
    size_t len = 0;
    double end = fx_now() + limit_s;
    while (fx_now() < end) {
        struct pollfd pf = {u->p.out, POLLIN, 0};
        if (poll(&pf, 1, 100) <= 0)
            continue;
        if (len + 1 >= n || read(u->p.out, line + len, 1) != 1)
            return -1;
        if (line[len] == '\n') {
            line[len] = 0;
            return 0;
        }
        len++;
    }
    return -1;
}

/* Start the camera (sensor 80x72, seed 11, screen slot 3, the serial
 * above; extra: more options, NULL-terminated, later ones win); 0 when
 * it is ready and $UMOCKDEV_DIR names its testbed. */
static inline int fx_u3v_start(fx_u3v *u, const char *const *extra)
{
    static char bin[PATH_MAX];
    int fd[2], n = 10;
    memset(u, 0, sizeof *u);
    u->in = -1;
    u->p.pid = -1;
    fx_bin(bin, sizeof bin, "specklab-fake-u3v");
    char *argv[24] = {bin, "--size", "80x72", "--seed", "11", "--screen-slot", "3",
                      "--serial", FX_U3V_SERIAL, "-q"};
    for (int i = 0; extra && extra[i] && n < 23; i++)
        argv[n++] = (char *)extra[i];
    argv[n] = NULL;
    if (access(bin, X_OK) != 0 || pipe2(fd, O_CLOEXEC) != 0)
        return -1;
    int rc = fx_spawn(&u->p, argv, FX_STDERR, fx_u3v_stdin, &fd[0]);
    close(fd[0]);
    u->in = fd[1];
    char line[PATH_MAX + 128];
    if (rc != 0 || fx_wait_ready(&u->p, line, sizeof line, 20) != 0 ||
        sscanf(line, "READY %4095s %63s", u->dir, u->node) != 2) {
        close(u->in);
        u->in = -1;
        fx_stop(&u->p, SIGKILL, 5);
        return -1;
    }
    setenv("UMOCKDEV_DIR", u->dir, 1);
    return 0;
}

/* Send "unplug" or "plug" and wait for its answer (UNPLUGGED, PLUGGED). */
static inline int fx_u3v_command(fx_u3v *u, const char *cmd, const char *answer)
{
    char line[256];
    size_t n = strlen(cmd);
    if (write(u->in, cmd, n) != (ssize_t)n || write(u->in, "\n", 1) != 1)
        return -1;
    while (fx_u3v_line(u, line, sizeof line, 10) == 0)
        if (strncmp(line, answer, strlen(answer)) == 0)
            return 0;
    return -1;
}

/* EOF on its stdin stops it; the testbed goes with it. */
static inline int fx_u3v_stop(fx_u3v *u)
{
    if (u->in >= 0)
        close(u->in);
    u->in = -1;
    return fx_stop(&u->p, SIGTERM, 5);
}

#endif
