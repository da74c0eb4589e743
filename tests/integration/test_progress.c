/* test_progress.c - cli/progress.c on a pseudo-terminal: the bar never
 * goes back, says its percentage and ETA, and stays silent on a pipe.
 * The waits are the bar's own redraw limit (10 per second), not a
 * synchronisation. */
#define _GNU_SOURCE
#include <fcntl.h>
#include <pty.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "progress.h"
#include "tcheck.h"

#define PAST_REDRAW_US 120000

/* Everything readable on fd now (non-blocking), NUL-terminated. */
static size_t drain(int fd, char *buf, size_t n)
{
    size_t got = 0;
    fcntl(fd, F_SETFL, fcntl(fd, F_GETFL) | O_NONBLOCK);
    for (ssize_t r; got + 1 < n && (r = read(fd, buf + got, n - 1 - got)) > 0;)
        got += (size_t)r;
    buf[got] = 0;
    return got;
}

/* The percentages drawn, in order. */
static int percentages(const char *s, int *out, int max)
{
    int n = 0;
    for (const char *p = s; n < max && (p = strchr(p, '%')); p++) {
        const char *q = p;
        while (q > s && q[-1] == ' ')
            q--;
        while (q > s && q[-1] >= '0' && q[-1] <= '9')
            q--;
        if (q < p)
            out[n++] = atoi(q);
    }
    return n;
}

TEST(bar_never_goes_back)
{
    int master = -1, slave = -1;
    CHECK(openpty(&master, &slave, NULL, NULL, NULL) == 0, "openpty");
    FILE *f = fdopen(slave, "w");
    progress *p = progress_new(f, 100);
    int active = progress_active(p);
    progress_update(p, 50, "frames");
    usleep(PAST_REDRAW_US);
    progress_update(p, 30, "frames"); /* a lower estimate: held at 50 */
    usleep(PAST_REDRAW_US);
    progress_update(p, 80, "frames");
    fflush(f);
    char buf[8192];
    drain(master, buf, sizeof buf);
    progress_free(p);
    fclose(f);
    close(master);
    int pc[8], n = percentages(buf, pc, 8);
    CHECK(active, "not drawn on a terminal");
    CHECK(n == 3 && pc[0] == 50 && pc[1] == 50 && pc[2] == 80,
          "percentages drawn: %d of them (%d %d %d): %.200s", n, n > 0 ? pc[0] : -1,
          n > 1 ? pc[1] : -1, n > 2 ? pc[2] : -1, buf);
    CHECK(strstr(buf, "ETA") && strstr(buf, "frames ["), "no label or ETA: %.200s", buf);
}

TEST(silent_on_a_pipe)
{
    int fd[2];
    CHECK(pipe(fd) == 0, "pipe");
    FILE *f = fdopen(fd[1], "w");
    progress *p = progress_new(f, 10);
    progress_update(p, 5, "x");
    progress_finish(p);
    progress_free(p);
    fclose(f);
    char buf[256];
    size_t got = drain(fd[0], buf, sizeof buf);
    close(fd[0]);
    CHECK(got == 0, "%zu bytes on a pipe: %s", got, buf);
}

TEST(eta_from_the_average_rate)
{
    CHECK_NEAR(progress_eta_s(10, 25, 100), 30, 1e-12);
    CHECK(progress_eta_s(10, 0, 100) < 0, "ETA with nothing done");
    char buf[16];
    CHECK(!strcmp(progress_fmt_time(buf, sizeof buf, 185), "3m05s"), "%s", buf);
}

TC_MAIN(TC_CASE(bar_never_goes_back), TC_CASE(silent_on_a_pipe),
        TC_CASE(eta_from_the_average_rate))
