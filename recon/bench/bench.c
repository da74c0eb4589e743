/* bench.c - see bench.h: measurement and scores.  The simulated data sets
 * are in bench_sim.c. */
#include "bench.h"

#include <errno.h>
#include <fftw3.h>
#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "io/cube.h"
#include "measure/metrics.h"

/* ---- measurement ---- */

typedef struct child_report {
    int status;                       /* SL_OK or the pipeline's code */
    int width, height, nframes, nrun;
    double r2_px, nangles, ntriples;   /* from the result's header */
    double crop_px, cutoff, rejected, pred;
    double cp_sep, cp_pa, cp_dm;      /* CPSEP, CPPA, CPDM */
    int method_run;
    char chosen[64];
    bench_verdict binary;
    double wall_s[BENCH_MAX_REPEAT], cpu_s[BENCH_MAX_REPEAT];
    char msg[SL_ERRMSG_MAX];
} child_report;

static double now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

static double cpu_s(void)
{
    struct rusage ru;
    getrusage(RUSAGE_SELF, &ru);
    return ru.ru_utime.tv_sec + 1e-6 * ru.ru_utime.tv_usec +
           ru.ru_stime.tv_sec + 1e-6 * ru.ru_stime.tv_usec;
}

static int write_all(int fd, const void *buf, size_t n)
{
    const char *p = buf;
    while (n > 0) {
        ssize_t k = write(fd, p, n);
        if (k < 0 && errno == EINTR)
            continue;
        if (k <= 0)
            return -1;
        p += k;
        n -= (size_t)k;
    }
    return 0;
}

/* Bytes read (short only at EOF or on error). */
static size_t read_all(int fd, void *buf, size_t n)
{
    char *p = buf;
    size_t got = 0;
    while (got < n) {
        ssize_t k = read(fd, p + got, n - got);
        if (k < 0 && errno == EINTR)
            continue;
        if (k <= 0)
            break;
        got += (size_t)k;
    }
    return got;
}

static void copy_verdict(const pipeline_binary *b, bench_verdict *v)
{
    v->status = b->status;
    v->source = b->source;
    v->sep_px = b->sep_px;
    v->sep_err_px = b->sep_err_px;
    v->pa_deg = b->pa_deg;
    v->pa_err_deg = b->pa_err_deg;
    v->dm_mag = b->dm_mag;
    v->dm_err_mag = b->dm_err_mag;
    snprintf(v->why, sizeof v->why, "%s", b->why);
}

/* The child: never returns.  _exit skips atexit handlers and stdio
 * buffers that belong to the parent. */
static void child_main(int fd, const char *cube, const pipeline_opts *o,
                       int repeat)
{
    fftw_forget_wisdom();
    fftwf_forget_wisdom();
    child_report *rep = calloc(1, sizeof *rep);
    pipeline_result r = {0};
    sl_err e = {0};
    const char *paths[] = {cube};
    if (!rep)
        _exit(3);
    for (int i = 0; i < repeat; i++) {
        pipeline_result_clear(&r);
        double t0 = now_s(), c0 = cpu_s();
        int rc = pipeline_run(paths, 1, o, &r, &e);
        double t1 = now_s(), c1 = cpu_s();
        if (rc != SL_OK) {
            rep->status = rc;
            snprintf(rep->msg, sizeof rep->msg, "%s", e.msg);
            break;
        }
        rep->wall_s[i] = t1 - t0;
        rep->cpu_s[i] = c1 - c0;
        rep->nrun = i + 1;
        rep->width = r.width;
        rep->height = r.height;
        rep->nframes = r.nframes;
        /* what ran, typed (pipeline.h's report): NAN where it does not apply */
        const pipeline_report *p = &r.report;
        int direct = p->method == PIPE_DIRECT, probed = p->probe.probed > 0;
        rep->r2_px = direct ? p->r2_px : NAN;
        rep->ntriples = direct ? (double)p->ntriples : NAN;
        rep->nangles = direct ? NAN : p->nangles;
        rep->cutoff = direct ? NAN : p->cutoff_cyc_px;
        rep->crop_px = probed ? p->probe.crop_w : NAN;
        rep->rejected = probed ? p->probe.rejected[1] + p->probe.rejected[2] +
                                 p->probe.rejected[3] + p->probe.rejected[4] : NAN;
        rep->pred = p->probe.chosen ? p->probe.pred_error : NAN;
        const pipeline_binary *v = &r.binary;
        rep->cp_sep = v->have_closure ? v->closure.sep_px : NAN;
        rep->cp_pa = v->have_closure ? v->closure.pa_deg : NAN;
        rep->cp_dm = v->have_closure ? v->closure.dm_mag : NAN;
        rep->method_run = p->method;
        snprintf(rep->chosen, sizeof rep->chosen, "%s", p->probe.chosen ? p->probe.chosen_label : "");
        copy_verdict(&r.binary, &rep->binary);
    }
    int bad = write_all(fd, rep, sizeof *rep);
    if (!bad && rep->status == SL_OK)
        bad = write_all(fd, r.image, sizeof(float) * (size_t)r.width *
                                         (size_t)r.height);
    _exit(bad ? 4 : 0);
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static double median(const double *v, int n)
{
    double s[BENCH_MAX_REPEAT];
    memcpy(s, v, sizeof(double) * (size_t)n);
    qsort(s, (size_t)n, sizeof s[0], cmp_double);
    return n % 2 ? s[n / 2] : 0.5 * (s[n / 2 - 1] + s[n / 2]);
}

/* Wait for the child; a failed run that left no message gets one from its
 * exit status. */
static int reap(pid_t pid, int rc, sl_err *err, double *maxrss_mb)
{
    int st = 0;
    struct rusage ru;
    memset(&ru, 0, sizeof ru);
    while (wait4(pid, &st, 0, &ru) < 0 && errno == EINTR)
        ;
    *maxrss_mb = ru.ru_maxrss / 1024.0; /* Linux: kB */
    if (rc == SL_OK && WIFSIGNALED(st))
        rc = sl_seterr(err, SL_EIO, "benchmark child killed by signal %d",
                       WTERMSIG(st));
    else if (rc == SL_OK && WIFEXITED(st) && WEXITSTATUS(st) != 0)
        rc = sl_seterr(err, SL_EIO, "benchmark child exited with %d",
                       WEXITSTATUS(st));
    return rc;
}

int bench_measure(const char *cube, const pipeline_opts *o, int repeat,
                  float *img, int w, int h, bench_timing *t, sl_err *err)
{
    memset(t, 0, sizeof *t);
    t->wall_s = t->cpu_s = t->wall_first_s = t->cpu_first_s = NAN;
    t->peak_rss_mb = t->r2_px = t->nangles = t->ntriples = NAN;
    t->crop_px = t->cutoff_cyc_px = t->rejected = t->pred_error = NAN;
    t->method_run = -1;
    t->binary.sep_px = t->binary.sep_err_px = t->binary.pa_deg = NAN;
    t->binary.pa_err_deg = t->binary.dm_mag = t->binary.dm_err_mag = NAN;
    if (repeat < 1 || repeat > BENCH_MAX_REPEAT || !cube || !o || !img)
        return sl_seterr(err, SL_EINVAL, "bench_measure: bad arguments "
                         "(repeat %d, 1..%d)", repeat, BENCH_MAX_REPEAT);
    child_report *rep = calloc(1, sizeof *rep);
    int fds[2];
    if (!rep)
        return sl_seterr(err, SL_ENOMEM, "out of memory");
    if (pipe(fds) != 0) {
        free(rep);
        return sl_seterr(err, SL_EIO, "pipe: %s", strerror(errno));
    }
    fflush(NULL);
    pid_t pid = fork();
    if (pid < 0) {
        int e = errno;
        close(fds[0]);
        close(fds[1]);
        free(rep);
        return sl_seterr(err, SL_EIO, "fork: %s", strerror(e));
    }
    if (pid == 0) {
        close(fds[0]);
        child_main(fds[1], cube, o, repeat);
    }
    close(fds[1]);
    int rc = SL_OK, short_read = 0;
    size_t npix = (size_t)w * (size_t)h;
    if (read_all(fds[0], rep, sizeof *rep) != sizeof *rep)
        short_read = 1;
    else if (rep->status != SL_OK)
        rc = sl_seterr(err, rep->status, "%s", rep->msg);
    else if (rep->width != w || rep->height != h)
        rc = sl_seterr(err, SL_EFORMAT, "%s: image is %dx%d, expected %dx%d",
                       cube, rep->width, rep->height, w, h);
    else if (read_all(fds[0], img, npix * sizeof(float)) != npix * sizeof(float))
        short_read = 1;
    if (rc != SL_OK)
        kill(pid, SIGKILL); /* it may be blocked writing the image */
    close(fds[0]);
    /* A short report means the child died: reap names the signal. */
    rc = reap(pid, rc, err, &t->peak_rss_mb);
    if (rc == SL_OK && short_read)
        rc = sl_seterr(err, SL_EIO, "benchmark child sent a short report");
    if (rc == SL_OK) {
        t->repeat = rep->nrun;
        t->wall_s = median(rep->wall_s, rep->nrun);
        t->cpu_s = median(rep->cpu_s, rep->nrun);
        t->wall_first_s = rep->wall_s[0];
        t->cpu_first_s = rep->cpu_s[0];
        t->nframes = rep->nframes;
        t->width = rep->width;
        t->height = rep->height;
        t->r2_px = rep->r2_px;
        t->nangles = rep->nangles;
        t->ntriples = rep->ntriples;
        t->crop_px = rep->crop_px;
        t->cutoff_cyc_px = rep->cutoff;
        t->rejected = rep->rejected;
        t->pred_error = rep->pred;
        t->cp_sep_px = rep->cp_sep;
        t->cp_pa_deg = rep->cp_pa;
        t->cp_dm_mag = rep->cp_dm;
        t->method_run = rep->method_run;
        snprintf(t->chosen, sizeof t->chosen, "%s", rep->chosen);
        t->binary = rep->binary;
    }
    free(rep);
    return rc;
}

double bench_baseline_rss_mb(void)
{
    fflush(NULL);
    pid_t pid = fork();
    if (pid < 0)
        return NAN;
    if (pid == 0)
        _exit(0);
    double mb = NAN;
    reap(pid, SL_OK, NULL, &mb);
    return mb;
}

/* ---- scores ---- */

/* One periodic 1-D Gaussian pass along rows (stride 1, count n, repeated
 * m times at pitch n) or columns; k: kernel of 2r+1 taps. */
static void smooth_axis(const float *in, float *out, int n, int m,
                        size_t step, size_t pitch, const double *k, int r)
{
    for (int j = 0; j < m; j++) {
        const float *a = in + (size_t)j * pitch;
        float *b = out + (size_t)j * pitch;
        for (int i = 0; i < n; i++) {
            double s = 0;
            for (int t = -r; t <= r; t++) {
                int q = ((i + t) % n + n) % n;
                s += k[t + r] * a[(size_t)q * step];
            }
            b[(size_t)i * step] = (float)s;
        }
    }
}

int bench_highpass(const float *in, float *out, int w, int h,
                   double sigma_px)
{
    if (!(sigma_px > 0) || w < 1 || h < 1)
        return SL_EINVAL;
    int r = (int)ceil(4 * sigma_px);
    size_t n = (size_t)w * (size_t)h;
    double *k = malloc(sizeof(double) * (size_t)(2 * r + 1));
    float *t1 = malloc(sizeof(float) * n), *t2 = malloc(sizeof(float) * n);
    int rc = SL_ENOMEM;
    if (!k || !t1 || !t2)
        goto free_all;
    double sum = 0;
    for (int i = -r; i <= r; i++)
        sum += k[i + r] = exp(-0.5 * i * i / (sigma_px * sigma_px));
    for (int i = 0; i <= 2 * r; i++)
        k[i] /= sum;
    smooth_axis(in, t1, w, h, 1, (size_t)w, k, r);  /* along x */
    smooth_axis(t1, t2, h, w, (size_t)w, 1, k, r);  /* along y */
    for (size_t i = 0; i < n; i++)
        out[i] = in[i] - t2[i];
    rc = SL_OK;
free_all:
    free(k);
    free(t1);
    free(t2);
    return rc;
}

static double wrap180(double d)
{
    d = fmod(d, 360.0);
    if (d > 180)
        d -= 360;
    if (d <= -180)
        d += 360;
    return d;
}

int bench_verdict_errors(const bench_verdict *v, const bench_truth *t,
                         double *dsep_px, double *dpa_deg, double *ddm_mag)
{
    *dsep_px = *dpa_deg = *ddm_mag = NAN;
    int amb = v->status == PIPE_BIN_AMBIGUOUS;
    if (!t->binary || (v->status != PIPE_BIN_MEASURED && !amb))
        return 0;
    *dsep_px = v->sep_px - t->sep_px;
    *ddm_mag = v->dm_mag - t->dm_mag;
    double d = wrap180(v->pa_deg - t->pa_deg);
    if (amb) /* modulo 180: into (-90, 90] */
        d = d > 90 ? d - 180 : d <= -90 ? d + 180 : d;
    *dpa_deg = d;
    return 1;
}

void bench_score_init(bench_score *s)
{
    s->c = s->c_hp = s->shift_x_px = s->shift_y_px = NAN;
    s->binary_found = 0;
    s->sep_px = s->pa_deg = s->dm_mag = NAN;
    s->sep_err_px = s->pa_err_deg = s->dm_err_mag = NAN;
}

int bench_score_image(const float *img, const bench_truth *t,
                      double hp_sigma_px, bench_score *s, sl_err *err)
{
    bench_score_init(s);
    int w = t->width, h = t->height;
    size_t n = (size_t)w * (size_t)h;
    for (size_t i = 0; i < n; i++)
        if (!isfinite(img[i]))
            return sl_seterr(err, SL_EDATA, "image pixel (%zu, %zu) is not "
                             "finite", i % (size_t)w, i / (size_t)w);
    metrics_plan *mp = metrics_plan_new(w, h, err);
    float *reg = malloc(sizeof(float) * n), *ha = malloc(sizeof(float) * n);
    int rc = SL_ENOMEM;
    if (!mp || !reg || !ha) {
        rc = sl_seterr(err, SL_ENOMEM, "out of memory");
        goto free_all;
    }
    if ((rc = metrics_register(mp, t->cophased, img, reg, &s->shift_x_px,
                               &s->shift_y_px)) != SL_OK) {
        sl_seterr(err, rc, "%s", metrics_errmsg(mp));
        goto free_all;
    }
    s->c = metrics_corr(t->cophased, reg, w, h);
    if ((rc = bench_highpass(t->cophased, ha, w, h, hp_sigma_px)) != SL_OK ||
        (rc = bench_highpass(reg, reg, w, h, hp_sigma_px)) != SL_OK) {
        sl_seterr(err, rc, "high-pass failed");
        goto free_all;
    }
    s->c_hp = metrics_corr(ha, reg, w, h);
    binary_result b;
    if (t->binary && metrics_plan_binary(mp, img, &b) == SL_OK) {
        s->binary_found = 1;
        s->sep_px = b.sep_px;
        s->pa_deg = b.pa_deg;
        s->dm_mag = b.dm_mag;
        s->sep_err_px = b.sep_px - t->sep_px;
        s->pa_err_deg = wrap180(b.pa_deg - t->pa_deg);
        s->dm_err_mag = b.dm_mag - t->dm_mag;
    }
    rc = SL_OK;
free_all:
    metrics_plan_free(mp);
    free(reg);
    free(ha);
    return rc;
}

void bench_pareto(const double *x, const double *y, int n,
                  unsigned char *front)
{
    for (int i = 0; i < n; i++) {
        front[i] = isfinite(x[i]) && isfinite(y[i]);
        for (int j = 0; j < n && front[i]; j++) {
            if (j == i || !isfinite(x[j]) || !isfinite(y[j]))
                continue;
            if (x[j] <= x[i] && y[j] <= y[i] && (x[j] < x[i] || y[j] < y[i]))
                front[i] = 0;
        }
    }
}
