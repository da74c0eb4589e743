/* test_mpi.c - specklab-mpi (mpi/): `mpirun -n N specklab-mpi recon`
 * gives the same image for N = 1, 2 and 4 (oversubscribed) with every
 * method, with and without the skips and auto, on a small camera-like
 * cube (96^2 x 24 frames: bias, 12-bit ADC, hot pixels, jitter, so the
 * detector, the crop and the probe all run); the image agrees with the
 * single-process one; a failing rank ends the job non-zero, named.
 * Skipped, with the reason, when the build has no MPI (Makefile, MPI). */
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>

#include "io/cube.h"
#include "tcheck.h"
#include "tmpdir_fx.h"

#ifndef SL_HAVE_MPI
#define SL_HAVE_MPI 0
#endif

/* Within this fraction of the image's maximum, for every N. */
#define TOL_REL 1e-6

/* The shell's exit status of the command, its output in dir/log. */
static int sh(const tmpdir *d, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static int sh(const tmpdir *d, const char *fmt, ...)
{
    char cmd[2048], full[2600];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(cmd, sizeof cmd, fmt, ap);
    va_end(ap);
    snprintf(full, sizeof full, "(%s) >%s/log 2>&1", cmd, d->dir);
    int st = system(full);
    return WIFEXITED(st) ? WEXITSTATUS(st) : 128;
}

static void log_text(const tmpdir *d, char *buf, size_t n)
{
    char p[128];
    snprintf(p, sizeof p, "%s/log", d->dir);
    FILE *f = fopen(p, "r");
    size_t got = f ? fread(buf, 1, n - 1, f) : 0;
    buf[got] = 0;
    if (f)
        fclose(f);
}

/* max |a - b| / max |a| of two images, *same when bit-identical, and a's
 * RECNFRM (frames used); < 0 when one cannot be read. */
static double image_diff(const char *a, const char *b, int *same, double *nframes)
{
    seq *x = NULL, *y = NULL;
    cube_meta mx;
    const char *pa[] = {a}, *pb[] = {b};
    double d = -1;
    if (cube_read(&x, &mx, pa, 1, 0, NULL) != SL_OK || cube_read(&y, NULL, pb, 1, 0, NULL) != SL_OK)
        goto free_all;
    if (x->width != y->width || x->height != y->height)
        goto free_all;
    size_t n = (size_t)x->width * x->height;
    double peak = 0, dmax = 0;
    for (size_t i = 0; i < n; i++) {
        peak = fmax(peak, fabs(x->data[i]));
        dmax = fmax(dmax, fabs((double)x->data[i] - y->data[i]));
    }
    *same = memcmp(x->data, y->data, n * sizeof *x->data) == 0;
    *nframes = 0;
    cube_meta_get_num(&mx, "RECNFRM", nframes);
    d = peak > 0 ? dmax / peak : -1;
free_all:
    seq_free(x);
    seq_free(y);
    return d;
}

static int ready(tc *t, tmpdir *d)
{
    if (!SL_HAVE_MPI)
        return 0;
    /* mpirun refuses root without these; CI runs as root */
    setenv("OMPI_ALLOW_RUN_AS_ROOT", "1", 1);
    setenv("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1", 1);
    if (!tmp_make(d))
        return 0;
    int rc = sh(d, "bin/specklab sim --scene binary --sep-arcsec 0.3 --pa-deg 40 --dm-mag 1 "
                "--size 96 --frames 24 --photons 1e4 --read-noise-e 3 --gain-e-per-adu 2 "
                "--bias-adu 100 --adc-bits 12 --hot-pixels 5 --jitter-px 2 --blind -o %s/c.fits",
                d->dir);
    if (rc != 0)
        t->failed = 1, snprintf(t->msg, sizeof t->msg, "specklab sim failed (%d)", rc);
    return rc == 0;
}

TEST(ranks_agree_for_every_method)
{
    if (!SL_HAVE_MPI)
        SKIP("built without MPI (pkg-config has neither ompi-c nor mpi, or MPI=0) "
             "(apt-get install libopenmpi-dev openmpi-bin)");
    tmpdir d;
    if (!ready(t, &d))
        return;
    static const char *const cfg[] = {
        "-m direct", "-m direct --skips all", "-m tsm", "-m tsm --skips all",
        "-m tsm-fourier", "-m tsm-fourier --skips all", "-m auto --binary"};
    static const int ranks[] = {1, 2, 4};
    char out[3][300], log[2048];
    for (size_t c = 0; c < sizeof cfg / sizeof cfg[0]; c++) {
        for (int i = 0; i < 3; i++) {
            snprintf(out[i], sizeof out[i], "%s/n%d.fits", d.dir, ranks[i]);
            int rc = sh(&d, "mpirun --oversubscribe -n %d bin/specklab-mpi recon %s/c.fits %s "
                        "-o %s --overwrite -q", ranks[i], d.dir, cfg[c], out[i]);
            log_text(&d, log, sizeof log);
            if (rc != 0)
                tmp_remove(&d);
            CHECK(rc == 0, "%s, %d ranks: exit %d: %s", cfg[c], ranks[i], rc, log);
        }
        printf("  %-28s", cfg[c]);
        for (int i = 1; i < 3; i++) {
            int same = 0;
            double n0 = 0, n1 = 0;
            double rel = image_diff(out[0], out[i], &same, &n0);
            int same1 = 0;
            image_diff(out[i], out[0], &same1, &n1);
            printf(" N=%d: %s", ranks[i], same ? "bit-identical" : "");
            if (!same)
                printf("%.2g of max", rel);
            int ok = rel >= 0 && rel <= TOL_REL && n0 == n1 && n0 == 24;
            if (!ok)
                tmp_remove(&d);
            CHECK(ok, "%s: %d ranks differ from 1 by %.3g of the maximum (tolerance %g), "
                  "frames used %g and %g", cfg[c], ranks[i], rel, TOL_REL, n0, n1);
        }
        printf("\n");
    }
    tmp_remove(&d);
}

TEST(split_run_matches_one_process)
{
    if (!SL_HAVE_MPI)
        SKIP("built without MPI (pkg-config has neither ompi-c nor mpi, or MPI=0)");
    tmpdir d;
    if (!ready(t, &d))
        return;
    char a[300], b[300];
    snprintf(a, sizeof a, "%s/one.fits", d.dir);
    snprintf(b, sizeof b, "%s/two.fits", d.dir);
    int rc1 = sh(&d, "bin/specklab recon %s/c.fits -m direct -o %s -q", d.dir, a);
    int rc2 = sh(&d, "mpirun --oversubscribe -n 2 bin/specklab-mpi recon %s/c.fits -m direct "
                 "-o %s -q", d.dir, b);
    int same = 0;
    double nf = 0, rel = image_diff(a, b, &same, &nf);
    tmp_remove(&d);
    CHECK(rc1 == 0 && rc2 == 0, "exits %d, %d", rc1, rc2);
    /* one process plans its FFTs by timing, the split run by rule: the
     * float transforms differ in their last bits, not more */
    CHECK(rel >= 0 && rel < 1e-5, "2 ranks differ from one process by %.3g of the maximum", rel);
}

TEST(failing_rank_ends_the_job_named)
{
    if (!SL_HAVE_MPI)
        SKIP("built without MPI (pkg-config has neither ompi-c nor mpi, or MPI=0)");
    tmpdir d;
    if (!ready(t, &d))
        return;
    /* the output exists: rank 0 refuses it (no --overwrite) and must not
     * leave rank 1 waiting for ever */
    int rc = sh(&d, "mpirun --oversubscribe -n 2 bin/specklab-mpi recon %s/c.fits -m tsm "
                "-o %s/c-truth.fits -q", d.dir, d.dir);
    char log[4096];
    log_text(&d, log, sizeof log);
    tmp_remove(&d);
    CHECK(rc != 0, "exit 0 with an existing output: %s", log);
    CHECK(strstr(log, "rank 0 of 2 failed"), "no rank named: %s", log);
}

/* The Slurm example runs outside Slurm too (mpirun: one rank per core)
 * and gives the one-rank image. */
TEST(slurm_example_runs)
{
    if (!SL_HAVE_MPI)
        SKIP("built without MPI (pkg-config has neither ompi-c nor mpi, or MPI=0)");
    tmpdir d;
    if (!ready(t, &d))
        return;
    char a[300], b[300], log[2048];
    snprintf(a, sizeof a, "%s/one.fits", d.dir);
    snprintf(b, sizeof b, "%s/slurm.fits", d.dir);
    int rc1 = sh(&d, "mpirun --oversubscribe -n 1 bin/specklab-mpi recon %s/c.fits -m tsm "
                 "-o %s -q", d.dir, a);
    int rc2 = sh(&d, "SPECKLAB_MPI=bin/specklab-mpi bash scripts/slurm/specklab-recon.sbatch "
                 "%s/c.fits %s -m tsm -q", d.dir, b);
    log_text(&d, log, sizeof log);
    int same = 0;
    double nf = 0, rel = image_diff(a, b, &same, &nf);
    tmp_remove(&d);
    CHECK(rc1 == 0 && rc2 == 0, "exits %d, %d: %s", rc1, rc2, log);
    CHECK(rel >= 0 && rel <= TOL_REL, "the sbatch image differs by %.3g of the maximum", rel);
}

/* bench --mpi: a row per rank count, the sums' size the same for 2 and 4
 * ranks (each rank sends the whole layout once per reduction) and none
 * for one, and the model's table; its times are not judged here. */
TEST(bench_reports_efficiency_and_model)
{
    if (!SL_HAVE_MPI)
        SKIP("built without MPI (pkg-config has neither ompi-c nor mpi, or MPI=0)");
    tmpdir d;
    if (!ready(t, &d))
        return;
    int rc = sh(&d, "bin/specklab bench --mpi --methods tsm-fourier --sizes 32 --frames 8");
    char log[8192];
    log_text(&d, log, sizeof log);
    tmp_remove(&d);
    CHECK(rc == 0, "exit %d: %s", rc, log);
    double mb[3] = {-1, -1, -1};
    for (int i = 0; i < 3; i++) {
        char head[32];
        snprintf(head, sizeof head, "%-12s %5d ", "tsm-fourier", (int[]){1, 2, 4}[i]);
        const char *row = strstr(log, head);
        CHECK(row, "no row for %d ranks: %s", (int[]){1, 2, 4}[i], log);
        double v[6];
        CHECK(sscanf(row + strlen(head), "%lf %lf %lf %lf %lf%% %lf", &v[0], &v[1], &v[2],
                     &v[3], &v[4], &v[5]) == 6, "row unreadable: %s", row);
        mb[i] = v[5];
    }
    CHECK(mb[0] == 0 && mb[1] > 0 && mb[1] == mb[2], "sums MB %g %g %g", mb[0], mb[1], mb[2]);
    CHECK(strstr(log, "model for N nodes") && strstr(log, "\n    64 "), "no model: %s", log);
}

TC_MAIN(TC_CASE(ranks_agree_for_every_method), TC_CASE(split_run_matches_one_process),
        TC_CASE(failing_rank_ends_the_job_named), TC_CASE(slurm_example_runs),
        TC_CASE(bench_reports_efficiency_and_model))
