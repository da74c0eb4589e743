/* progress.c - see progress.h. */
#include "progress.h"

#include <math.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>
#include <sys/ioctl.h>
#include <time.h>
#include <unistd.h>

#define REDRAW_S 0.1
#define LINE_MAX_CH 256

struct progress {
    FILE *f;
    int tty;
    double total;
    double done;   /* the most reported so far: the bar never goes back */
    double t0_s, last_s;
    int drawn;   /* a bar is on the line */
};

static double mono_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec + ts.tv_nsec * 1e-9;
}

progress *progress_new(FILE *f, double total)
{
    progress *p = calloc(1, sizeof *p);
    if (!p)
        abort(); /* a few bytes: nothing sensible to do without them */
    p->f = f;
    p->tty = f && isatty(fileno(f));
    p->total = total > 0 ? total : 1;
    p->t0_s = mono_s();
    p->last_s = -1;
    return p;
}

void progress_free(progress *p)
{
    if (!p)
        return;
    progress_finish(p);
    free(p);
}

int progress_active(const progress *p)
{
    return p && p->tty;
}

double progress_eta_s(double elapsed_s, double done, double total)
{
    if (!(done > 0) || !(elapsed_s >= 0))
        return -1;
    if (done >= total)
        return 0;
    return elapsed_s * (total - done) / done;
}

const char *progress_fmt_time(char *buf, size_t n, double s)
{
    if (!(s >= 0) || !isfinite(s))
        snprintf(buf, n, "--");
    else if (s >= 3600)
        snprintf(buf, n, "%dh%02dm", (int)(s / 3600), (int)fmod(s / 60, 60));
    else if (s >= 60)
        snprintf(buf, n, "%dm%02ds", (int)(s / 60), (int)fmod(s, 60));
    else
        snprintf(buf, n, "%ds", (int)(s + 0.5));
    return buf;
}

static int term_width(FILE *f)
{
    struct winsize ws;
    if (ioctl(fileno(f), TIOCGWINSZ, &ws) == 0 && ws.ws_col >= 20)
        return ws.ws_col < LINE_MAX_CH ? ws.ws_col : LINE_MAX_CH;
    return 80;
}

void progress_update(progress *p, double done, const char *label)
{
    if (!p || !p->tty)
        return;
    /* Callers estimate; a later, lower estimate (a run that restarted a
     * count) must not move the bar back. */
    if (done < p->done)
        done = p->done;
    p->done = done;
    double now = mono_s();
    if (p->last_s >= 0 && now - p->last_s < REDRAW_S && done < p->total)
        return;
    p->last_s = now;
    double frac = done / p->total;
    frac = frac < 0 ? 0 : frac > 1 ? 1 : frac;
    char eta[32], el[32];
    progress_fmt_time(eta, sizeof eta, progress_eta_s(now - p->t0_s, done, p->total));
    progress_fmt_time(el, sizeof el, now - p->t0_s);
    char tail[96];
    snprintf(tail, sizeof tail, " %3d%% %s, ETA %s", (int)(frac * 100), el, eta);
    int width = term_width(p->f) - 1; /* never touch the last column: no wrap */
    const char *lab = label ? label : "";
    int barw = width - (int)strlen(tail) - 3 - (int)strlen(lab);
    if (barw > 40)
        barw = 40;
    char line[LINE_MAX_CH + 1];
    int n = 0;
    if (barw >= 10) {
        int fill = (int)(frac * barw + 0.5);
        n = snprintf(line, sizeof line, "%s [", lab);
        for (int i = 0; i < barw && n < LINE_MAX_CH - 1; i++)
            line[n++] = i < fill ? '#' : '.';
        line[n++] = ']';
        line[n] = '\0';
    } else {
        n = snprintf(line, sizeof line, "%s", lab);
    }
    snprintf(line + n, sizeof line - (size_t)n, "%s", tail);
    line[width < LINE_MAX_CH ? width : LINE_MAX_CH] = '\0';
    fprintf(p->f, "\r\033[K%s", line);
    fflush(p->f);
    p->drawn = 1;
}

void progress_note(progress *p, const char *fmt, ...)
{
    if (!p)
        return;
    if (p->drawn) {
        fputs("\r\033[K", p->f);
        p->drawn = 0;
        p->last_s = -1; /* redraw at the next update */
    }
    va_list ap;
    va_start(ap, fmt);
    vfprintf(p->f, fmt, ap);
    va_end(ap);
    fputc('\n', p->f);
    fflush(p->f);
}

void progress_finish(progress *p)
{
    if (p && p->drawn) {
        fputs("\r\033[K", p->f);
        fflush(p->f);
        p->drawn = 0;
    }
}
