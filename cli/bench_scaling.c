/* bench_scaling.c - see bench_scaling.h.
 *
 * Each point is pipeline_run in this process (after one untimed run at
 * each thread count, so that FFT plans and the page cache are warm: each
 * thread count plans its own per-thread handles).  The --repeat runs are
 * interleaved across the thread counts (1, 2, 1, 2, ...), so that a
 * shared host's load, which drifts over minutes (+-25 % here, once 2x),
 * falls on every count alike; each point is the fastest of its runs, the
 * least disturbed, with its own stages (pipeline_report.stage_s), and the
 * median is printed beside it.
 * A T-thread run is pinned to T of the process's CPUs (sched_setaffinity;
 * the pipeline's threads, made inside the run, inherit it), so that T
 * threads means T cores: the read-ahead thread and the caller then share
 * them, as they would on a machine with T cores.  Unpinned, a 1-thread run
 * also had the read-ahead on the second core (its CPU time ~1.3x its wall
 * time at 512^2), which made t_1, and so every speed-up, look smaller.
 * cpu_s (user + system of every thread, getrusage) shows the work done.
 * The parallel fraction is Amdahl's from one to T cores:
 *     p = (1 - t_T / t_1) / (1 - 1 / T)
 * for the whole run and for each stage: a stage that does not gain is
 * serial, whatever its share.  On a shared machine the load average is
 * printed first: a busy machine makes every thread count look worse.
 * Amdahl's p counts two different losses as serial: time when cores sat
 * idle (one thread working, waits, I/O, a host taking the vCPU), and
 * extra CPU the T threads spent for the same work (shared caches and
 * memory bandwidth).  They are split with the CPU time: a run whose work
 * is parallel but for s seconds on one core has cpu_T = s + T (t_T - s),
 * so
 *     s = (T t_T - cpu_T) / (T - 1),   overhead = cpu_T / cpu_1 - 1;
 * 1 - s / t_1 is the fraction of the work that spread, the one that
 * bounds T -> infinity, and the overhead is the machine's (2 cores
 * sharing one L3 here; other on a machine with more cache per core).
 */
#define _GNU_SOURCE /* sched_setaffinity, CPU_SET */
#include "bench_scaling.h"

#include <sched.h>
#include <sys/resource.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "bench/bench.h"
#include "pipeline/pipeline.h"

#define MAX_T 6

typedef struct point {
    double total_s, cpu_s, stage_s[PIPE_NSTAGES];
} point;

static double cpu_now_s(void)
{
    struct rusage ru;
    getrusage(RUSAGE_SELF, &ru);
    return ru.ru_utime.tv_sec + ru.ru_stime.tv_sec +
           1e-6 * (ru.ru_utime.tv_usec + ru.ru_stime.tv_usec);
}

/* Restrict this thread (and the threads it makes) to the first n CPUs of
 * *all; n <= 0: all of them.  0, or -1 when the kernel refuses. */
static int pin_cpus(const cpu_set_t *all, int n)
{
    cpu_set_t set;
    CPU_ZERO(&set);
    for (int c = 0, k = 0; c < CPU_SETSIZE && (n <= 0 || k < n); c++)
        if (CPU_ISSET(c, all))
            CPU_SET(c, &set), k++;
    return sched_setaffinity(0, sizeof set, &set) == 0 ? 0 : -1;
}

/* One run of method at nthreads, pinned to nthreads of the CPUs in *all,
 * into *pt. */
static int measure(const char *cube, const cpu_set_t *all, int method, int nthreads,
                   int measure_plans, point *pt)
{
    pipeline_opts o;
    pipeline_opts_defaults(&o);
    o.method = method;
    o.nthreads = nthreads;
    o.fftw_measure = measure_plans;
    pipeline_result res;
    sl_err e;
    const char *paths[] = {cube};
    if (pin_cpus(all, nthreads) != 0)
        fprintf(stderr, "specklab bench --scaling: cannot pin to %d CPUs; running unpinned\n",
                nthreads);
    double c0 = cpu_now_s();
    int st = pipeline_run(paths, 1, &o, &res, &e);
    pin_cpus(all, 0);
    if (st != SL_OK) {
        fprintf(stderr, "specklab bench --scaling: %s: %s\n", pipeline_method_name(method),
                e.msg);
        return 1;
    }
    pt->total_s = res.elapsed_s;
    pt->cpu_s = cpu_now_s() - c0;
    memcpy(pt->stage_s, res.report.stage_s, sizeof pt->stage_s);
    pipeline_result_clear(&res);
    return 0;
}

/* The fastest of n runs into *best, and the median wall time. */
static double best_and_median(point *runs, int n, point *best)
{
    for (int i = 1; i < n; i++)   /* insertion sort by total */
        for (int j = i; j > 0 && runs[j].total_s < runs[j - 1].total_s; j--) {
            point t = runs[j];
            runs[j] = runs[j - 1], runs[j - 1] = t;
        }
    *best = runs[0];
    return runs[n / 2].total_s;
}

static double amdahl(double t1, double tn, int n)
{
    return t1 > 0 && n > 1 ? (1 - tn / t1) / (1 - 1.0 / n) : NAN;
}

static void print_row(const char *method, int nthreads, const point *p, const point *one,
                      double median_s)
{
    printf("%-12s %7d %8.3f %6.2f", method, nthreads, p->total_s, p->cpu_s);
    for (int k = 0; k < PIPE_NSTAGES; k++)
        printf(" %7.3f", p->stage_s[k]);
    printf(" %7.2f %8.3f\n", one->total_s / p->total_s, median_s);
}

/* The fraction of the run, and of each stage, that gained from 1 to n. */
static void print_fraction(const char *method, const point *one, const point *pn, int n)
{
    printf("%s, 1 -> %d threads: parallel fraction %.0f %% (Amdahl); per stage (share of "
           "the 1-thread run, fraction):", method, n, 100 * amdahl(one->total_s, pn->total_s, n));
    for (int k = 0; k < PIPE_NSTAGES; k++)
        if (one->stage_s[k] > 0.005 * one->total_s)
            printf(" %s %.0f %%, %.0f %%;", pipeline_stage_name(k),
                   100 * one->stage_s[k] / one->total_s,
                   100 * amdahl(one->stage_s[k], pn->stage_s[k], n));
    printf("\n");
    double serial_s = (n * pn->total_s - pn->cpu_s) / (n - 1);
    printf("%s, on %d: %.3f s with cores idle (%.1f %% of the 1-thread run: %.1f %% of the "
           "work spread), CPU %+.0f %% (the threads' contention)\n", method, n, serial_s,
           100 * serial_s / one->total_s, 100 * (1 - serial_s / one->total_s),
           100 * (pn->cpu_s / one->cpu_s - 1));
}

/* The thread counts: 1, 2, 4 ... up to the CPUs this process may use (at
 * least 1 and 2). */
static int thread_counts(const cpu_set_t *all, int *t)
{
    int cores = CPU_COUNT(all), n = 0;
    for (int k = 1; n < MAX_T && (k <= cores || k <= 2); k *= 2)
        t[n++] = k;
    return n;
}

static int run_methods(const bench_args *a, const char *cube, char **methods)
{
    cpu_set_t all;
    if (sched_getaffinity(0, sizeof all, &all) != 0) {
        fprintf(stderr, "specklab bench --scaling: sched_getaffinity failed\n");
        return 1;
    }
    int t[MAX_T], nt = thread_counts(&all, t);
    printf("%-12s %7s %8s %6s", "method", "threads", "total_s", "cpu_s");
    for (int k = 0; k < PIPE_NSTAGES; k++)
        printf(" %7s", pipeline_stage_name(k));
    printf(" %7s %8s\n", "speedup", "median_s");
    for (int m = 0; methods[m]; m++) {
        int id;
        if (pipeline_method_parse(methods[m], &id) != SL_OK || id == PIPE_AUTO) {
            fprintf(stderr, "specklab bench --scaling: method '%s': want direct, tsm or "
                    "tsm-fourier\n", methods[m]);
            return 2;
        }
        point warm, pts[MAX_T], runs[MAX_T][BENCH_MAX_REPEAT];
        double median[MAX_T];
        for (int i = 0; i < nt; i++)   /* untimed: each count plans its own handles */
            if (measure(cube, &all, id, t[i], !a->estimate, &warm))
                return 1;
        for (int r = 0; r < a->repeat; r++)
            for (int i = 0; i < nt; i++)
                if (measure(cube, &all, id, t[i], !a->estimate, &runs[i][r]))
                    return 1;
        for (int i = 0; i < nt; i++)
            median[i] = best_and_median(runs[i], a->repeat, &pts[i]);
        for (int i = 0; i < nt; i++)
            print_row(methods[m], t[i], &pts[i], &pts[0], median[i]);
        fflush(stdout);
        print_fraction(methods[m], &pts[0], &pts[nt - 1], t[nt - 1]);
    }
    return 0;
}

int bench_scaling_run(const bench_args *a)
{
    int size = a->sizes ? atoi(a->sizes) : 200, frames = a->frames ? atoi(a->frames) : 100;
    if (size < 16 || frames < 2) {
        fprintf(stderr, "specklab bench --scaling: --sizes >= 16 and --frames >= 2\n");
        return 2;
    }
    char *dir = a->dir ? g_strdup(a->dir) : g_dir_make_tmp("specklab-scaling-XXXXXX", NULL);
    char *cube = dir ? g_build_filename(dir, "cube.fits", NULL) : NULL;
    char **methods = g_strsplit(a->methods ? a->methods : "direct,tsm,tsm-fourier", ",", -1);
    int rc = 1;
    bench_sim s;
    bench_sim_defaults(&s);
    s.scene = "binary";
    s.width = s.height = size;
    s.nframes = frames;
    s.seed = (uint64_t)a->seed;
    sl_err e;
    if (!cube || g_mkdir_with_parents(dir, 0755) != 0 ||
        bench_sim_write(&s, cube, NULL, &e) != SL_OK) {
        fprintf(stderr, "specklab bench --scaling: simulating: %s\n", cube ? e.msg : "no directory");
        goto free_all;
    }
    double load[1] = {0};
    if (getloadavg(load, 1) != 1)
        load[0] = NAN;
    printf("specklab bench --scaling: %d^2 x %d frames, noiseless binary, %s plans, %ld cores, "
           "load average %.1f before, fastest of %d runs interleaved over the thread counts "
           "(their median in median_s), each pinned to as many CPUs as threads; cpu_s: every "
           "thread's CPU time; stages in s of that run (pipeline.h, enum pipeline_stage)\n", size, frames, a->estimate ? "ESTIMATE" : "MEASURE",
           sysconf(_SC_NPROCESSORS_ONLN), load[0], a->repeat);
    rc = run_methods(a, cube, methods);
free_all:
    if (cube && !a->dir) {
        unlink(cube);
        rmdir(dir);
    }
    g_strfreev(methods);
    g_free(cube);
    g_free(dir);
    return rc;
}
