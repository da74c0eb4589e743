/* test_pipeline_share.c - a run split over processes without MPI
 * (pipeline.h, pipeline_share): the estimators' partial sums exported,
 * merged and loaded give what one accumulator over every frame gives; two
 * forked processes joined by a socket pair, as two ranks, give the
 * one-process image for direct, TSM and auto with every skip; the rank
 * that is not 0 stops after its last sums (SL_EEND). */
#include <fftw3.h>
#include <stdlib.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include "io/cube.h"
#include "pipeline/pipeline.h"
#include "sim/sim.h"
#include "spectra/bispec.h"
#include "spectra/powspec.h"
#include "tcheck.h"
#include "tmpdir_fx.h"
#include "tsm/tsm.h"

#define SIDE 48
#define NFRAMES 20

/* The simulator of a binary at 1e4 photons per frame, SIDE^2. */
static sim *binary_sim(uint64_t seed)
{
    sim_opts so;
    sim_opts_defaults(&so);
    so.seed = seed;
    so.width = so.height = SIDE;
    so.nframes = NFRAMES;
    so.photons_per_frame = 1e4;
    so.fftw_flags = FFTW_ESTIMATE;
    mask *holes = NULL;
    scene *pair_scene = NULL;
    sim *out = NULL;
    if (mask_named(&holes, "nrm17", NULL) == SL_OK &&
        scene_named(&pair_scene, "binary", 0.3, 250, 1.0, NULL) == SL_OK)
        sim_new(&out, &so, holes, pair_scene, NULL);
    scene_free(pair_scene);
    mask_free(holes);
    return out;
}

/* NFRAMES frames into frames and, with path, a cube with SIMPHOT. */
static int simulate(float *frames, const char *path, uint64_t seed)
{
    sim *s = binary_sim(seed);
    cube_writer *w = NULL;
    cube_meta md;
    cube_meta_init(&md);
    cube_meta_set_num(&md, "SIMPHOT", 1e4, NULL);
    cube_meta_set_num(&md, "SIMGAIN", 1, NULL);
    int rc = s ? SL_OK : SL_EINVAL;
    if (rc == SL_OK && path)
        rc = cube_writer_open(&w, path, SIDE, SIDE, -32, &md, NULL);
    for (int k = 0; rc == SL_OK && k < NFRAMES; k++) {
        float *f = frames + (size_t)k * SIDE * SIDE;
        if ((rc = sim_frame(s, k, f)) == SL_OK && w)
            rc = cube_writer_append(w, f);
    }
    if (rc == SL_OK && w)
        rc = cube_writer_close(w);
    cube_writer_free(w);
    sim_free(s);
    return rc;
}

static double rel_diff(const float *a, const float *b, size_t n)
{
    double peak = 0, d = 0;
    for (size_t i = 0; i < n; i++) {
        peak = fmax(peak, fabs(a[i]));
        d = fmax(d, fabs((double)a[i] - b[i]));
    }
    return peak > 0 ? d / peak : INFINITY;
}

/* The partial sums of frames [0, k) and [k, n), merged, against one
 * accumulator over all: the power spectrum (exact sums of the same
 * terms, re-associated) and the bispectrum's and TSM's images. */
TEST(partial_sums_merge_to_the_whole)
{
    size_t npx = (size_t)SIDE * SIDE;
    float *fr = malloc(npx * NFRAMES * sizeof *fr), *ia = malloc(npx * sizeof *ia),
          *ib = malloc(npx * sizeof *ib);
    CHECK(fr && ia && ib && simulate(fr, NULL, 1) == SL_OK, "simulation");
    powspec_opts po;
    powspec_opts_defaults(&po);
    po.measure = 0;
    bispec_opts bo;
    bispec_opts_defaults(&bo);
    bo.measure = 0;
    tsm_opts to;
    tsm_opts_defaults(&to);
    to.nangles = 36;
    to.fftw_flags = FFTW_ESTIMATE;
    powspec *pa = powspec_new(SIDE, SIDE, &po, NULL), *pb = powspec_new(SIDE, SIDE, &po, NULL);
    bispec *ba = bispec_new(SIDE, SIDE, &bo, NULL), *bb = bispec_new(SIDE, SIDE, &bo, NULL);
    tsm *ta = tsm_new(SIDE, SIDE, &to, NULL), *tb = tsm_new(SIDE, SIDE, &to, NULL);
    CHECK(pa && pb && ba && bb && ta && tb, "accumulators");
    for (int k = 0; k < NFRAMES; k++) {   /* a: every frame; b: from frame 7 */
        const float *f = fr + (size_t)k * npx;
        powspec_add(pa, f), bispec_add(ba, f), tsm_add(ta, f);
        if (k >= 7)
            powspec_add(pb, f), bispec_add(bb, f), tsm_add(tb, f);
    }
    /* the first 7 frames' part, then b's merged into it, loaded into b */
    powspec *pc = powspec_new(SIDE, SIDE, &po, NULL);
    bispec *bc = bispec_new(SIDE, SIDE, &bo, NULL);
    tsm *tc_ = tsm_new(SIDE, SIDE, &to, NULL);
    for (int k = 0; k < 7; k++) {
        const float *f = fr + (size_t)k * npx;
        powspec_add(pc, f), bispec_add(bc, f), tsm_add(tc_, f);
    }
    size_t np = powspec_partial(pc, NULL), nb = bispec_partial(bc, NULL), nt = tsm_partial(tc_, NULL);
    double *s0 = malloc((np + nb + nt) * sizeof *s0), *s1 = malloc((np + nb + nt) * sizeof *s1);
    CHECK(s0 && s1, "memory");
    powspec_partial(pc, s0), bispec_partial(bc, s0 + np), tsm_partial(tc_, s0 + np + nb);
    powspec_partial(pb, s1), bispec_partial(bb, s1 + np), tsm_partial(tb, s1 + np + nb);
    pipeline_sums_merge(s0, s1, np + nb + nt);
    powspec_partial_load(pb, s0), bispec_partial_load(bb, s0 + np), tsm_partial_load(tb, s0 + np + nb);
    CHECK(powspec_nframes(pb) == NFRAMES && bispec_nframes(bb) == NFRAMES &&
          tsm_nframes(tb) == NFRAMES, "frame counts %d %d %d", powspec_nframes(pb),
          bispec_nframes(bb), tsm_nframes(tb));
    double *psa = malloc(npx * sizeof *psa), *psb = malloc(npx * sizeof *psb), dps = 0;
    CHECK(psa && psb && powspec_result(pa, psa) == SL_OK && powspec_result(pb, psb) == SL_OK,
          "power spectra");
    for (size_t i = 0; i < npx; i++)
        dps = fmax(dps, fabs(psa[i] - psb[i]) / psa[0]);
    CHECK(dps < 1e-12, "power spectrum differs by %.3g of its DC", dps);
    CHECK(bispec_image(ba, NULL, ia) == SL_OK && bispec_image(bb, NULL, ib) == SL_OK, "bispec");
    double db = rel_diff(ia, ib, npx);
    CHECK(tsm_result(ta, ia) == SL_OK && tsm_result(tb, ib) == SL_OK, "tsm");
    double dt = rel_diff(ia, ib, npx);
    CHECK(db < 1e-6 && dt < 1e-6, "images differ: bispectrum %.3g, TSM %.3g of the maximum", db, dt);
    free(psa), free(psb), free(s0), free(s1), free(fr), free(ia), free(ib);
    powspec_free(pa), powspec_free(pb), powspec_free(pc);
    bispec_free(ba), bispec_free(bb), bispec_free(bc);
    tsm_free(ta), tsm_free(tb), tsm_free(tc_);
}

/* Two ranks as two processes joined by a socket pair: the transport a
 * caller of pipeline_share brings (specklab-mpi brings MPI). */
typedef struct pair {
    int rank, fd;
    pipeline_share hooks;
} pair;

static int put(int fd, const void *buf, size_t n)
{
    for (const char *p = buf; n > 0;) {
        ssize_t k = write(fd, p, n);
        if (k <= 0)
            return SL_EIO;
        p += k, n -= (size_t)k;
    }
    return SL_OK;
}

static int get(int fd, void *buf, size_t n)
{
    for (char *p = buf; n > 0;) {
        ssize_t k = read(fd, p, n);
        if (k <= 0)
            return SL_EIO;
        p += k, n -= (size_t)k;
    }
    return SL_OK;
}

static int pair_reduce(void *ctx, double *sums, size_t n, int last)
{
    pair *p = ctx;
    if (p->rank == 1) {
        int rc = put(p->fd, sums, n * sizeof *sums);
        return rc != SL_OK ? rc : last ? SL_EEND : get(p->fd, sums, n * sizeof *sums);
    }
    double *part = calloc(n, sizeof *part);
    int rc = part ? get(p->fd, part, n * sizeof *part) : SL_ENOMEM;
    if (rc == SL_OK)
        pipeline_sums_merge(sums, part, n);
    free(part);
    return rc != SL_OK || last ? rc : put(p->fd, sums, n * sizeof *sums);
}

static int pair_agree(void *ctx, void *buf, size_t bytes)
{
    pair *p = ctx;
    return p->rank == 0 ? put(p->fd, buf, bytes) : get(p->fd, buf, bytes);
}

/* The cube reconstructed by one process, then by two; *rel: their
 * images' difference over the maximum; *frames: the two runs' frames
 * used. */
static int split_run(const char *cube, const char *method, const char *skips, double *rel,
                     int frames[2], char *msg, size_t n)
{
    pipeline_opts o;
    pipeline_opts_defaults(&o);
    sl_err e = {0};
    if (pipeline_opts_set(&o, "method", method, &e) != SL_OK ||
        pipeline_opts_set(&o, "skips", skips, &e) != SL_OK)
        return snprintf(msg, n, "%s", e.msg), -1;
    o.fftw_measure = 0; /* plans by rule: the same transforms in both runs */
    pipeline_result one, two;
    if (pipeline_run(&cube, 1, &o, &one, &e) != SL_OK)
        return snprintf(msg, n, "one process: %s", e.msg), -1;
    int sv[2];
    if (socketpair(AF_UNIX, SOCK_STREAM, 0, sv) != 0)
        return snprintf(msg, n, "socketpair"), -1;
    fflush(NULL);
    pid_t child = fork();
    pair p = {child == 0 ? 1 : 0, child == 0 ? sv[1] : sv[0], {0}};
    close(child == 0 ? sv[0] : sv[1]);
    p.hooks = (pipeline_share){p.rank, 2, pair_reduce, pair_agree, &p};
    o.share = &p.hooks;
    int rc = pipeline_run(&cube, 1, &o, &two, &e);
    if (child == 0)
        _exit(rc == SL_EEND ? 0 : 1);   /* rank 1: its part ends at the last sums */
    int st = 0;
    waitpid(child, &st, 0);
    close(p.fd);
    if (rc != SL_OK || !WIFEXITED(st) || WEXITSTATUS(st) != 0) {
        pipeline_result_clear(&one);
        return snprintf(msg, n, "two processes: rank 0 %d (%s), rank 1 status %d", rc, e.msg, st), -1;
    }
    *rel = rel_diff(one.image, two.image, (size_t)one.width * one.height);
    frames[0] = one.nframes, frames[1] = two.nframes;
    pipeline_result_clear(&one);
    pipeline_result_clear(&two);
    return 0;
}

TEST(two_processes_make_the_one_process_image)
{
    tmpdir d;
    float *fr = malloc((size_t)SIDE * SIDE * NFRAMES * sizeof *fr);
    CHECK(fr && tmp_make(&d), "setup");
    const char *cube = tmp_path(&d, 0, "c.fits");
    int sim_rc = simulate(fr, cube, 1);
    free(fr);
    static const char *const cfg[][2] = {
        {"direct", "none"}, {"direct", "all"}, {"tsm", "none"}, {"tsm-fourier", "all"},
        {"auto", "all"}};
    char msg[700] = "";
    double rel[5] = {0};
    int frames[5][2] = {{0}}, rc = sim_rc;
    for (int i = 0; rc == SL_OK && i < 5; i++)
        rc = split_run(cube, cfg[i][0], cfg[i][1], &rel[i], frames[i], msg, sizeof msg);
    tmp_remove(&d);
    CHECK(sim_rc == SL_OK, "simulation %d", sim_rc);
    CHECK(rc == 0, "%s", msg);
    for (int i = 0; i < 5; i++) {
        printf("  %s, skips %s: %s %.2g of the maximum\n", cfg[i][0], cfg[i][1],
               rel[i] == 0 ? "bit-identical," : "differs by", rel[i]);
        CHECK(rel[i] <= 1e-6 && frames[i][0] == frames[i][1] && frames[i][1] > 0,
              "%s, skips %s: %.3g of the maximum, frames %d and %d", cfg[i][0], cfg[i][1],
              rel[i], frames[i][0], frames[i][1]);
    }
}

/* Two ranks given different cubes of one size: rank 1 sees that its
 * first frames do not say what rank 0's say and stops, naming itself;
 * rank 0 then fails on the lost peer instead of waiting for ever. */
TEST(ranks_that_disagree_stop)
{
    tmpdir d;
    float *fr = malloc((size_t)SIDE * SIDE * NFRAMES * sizeof *fr);
    CHECK(fr && tmp_make(&d), "setup");
    const char *a = tmp_path(&d, 0, "a.fits"), *b = tmp_path(&d, 1, "b.fits");
    int sim_rc = simulate(fr, a, 1);
    if (sim_rc == SL_OK)
        sim_rc = simulate(fr, b, 2);
    free(fr);
    int sv[2];
    CHECK(sim_rc == SL_OK && socketpair(AF_UNIX, SOCK_STREAM, 0, sv) == 0, "setup");
    fflush(NULL);
    pid_t child = fork();
    pair p = {child == 0 ? 1 : 0, child == 0 ? sv[1] : sv[0], {0}};
    close(child == 0 ? sv[0] : sv[1]);
    p.hooks = (pipeline_share){p.rank, 2, pair_reduce, pair_agree, &p};
    pipeline_opts o;
    pipeline_opts_defaults(&o);
    o.method = PIPE_TSM;
    o.fftw_measure = 0;
    o.share = &p.hooks;
    pipeline_result r;
    sl_err e = {0};
    const char *cube = child == 0 ? b : a;
    int rc = pipeline_run(&cube, 1, &o, &r, &e);
    if (child == 0) {
        close(p.fd);
        _exit(rc == SL_EDATA && strstr(e.msg, "rank 1") && strstr(e.msg, "rank 0's") ? 0 : 1);
    }
    close(p.fd);
    int st = 0;
    waitpid(child, &st, 0);
    if (rc == SL_OK)
        pipeline_result_clear(&r);
    tmp_remove(&d);
    CHECK(WIFEXITED(st) && WEXITSTATUS(st) == 0, "rank 1 did not refuse its frames (status %d)", st);
    CHECK(rc != SL_OK, "rank 0 made an image of two different cubes");
}

TC_MAIN(TC_CASE(partial_sums_merge_to_the_whole), TC_CASE(two_processes_make_the_one_process_image),
        TC_CASE(ranks_that_disagree_stop))
