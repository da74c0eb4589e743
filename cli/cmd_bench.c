/* cmd_bench.c - `specklab bench`: run time against error on simulated
 * cubes with known truth.
 *
 * A sweep is a Cartesian product: scenes x sizes x frame counts x photon
 * levels (the data sets, each simulated once into a FITS cube with its
 * TRUTH and COPHASED extensions) times configurations (method x R2 for
 * direct, x projections for TSM, x without/with a reference).  Each point
 * is pipeline_run on the FITS file, end to end, in a forked child
 * (bench_measure: wall and CPU time, the child's own peak RSS), scored
 * against the cophased image (bench_score_image).  The reference variant
 * reconstructs with a point-source sequence simulated with another seed
 * (seed + 1000, same size, frames and photons) and the cophased point
 * source as --target.
 *
 * Presets: --quick (a handful of points, < 1 min, `make bench`),
 * --skips-report (bench_skips.c: each skip on and off, and auto against
 * fixed TSM-180), --speed (the speed targets at 100 frames of 200^2,
 * median of 5 runs, checked), the default (the method grid on three
 * scenes and two photon levels, plus size and frame-count scaling; a few
 * minutes), --paper (Table 2's layout at 200^2 and 128^2, or --sizes, and
 * a binaries table at the first size; it ignores the other selections),
 * --blind (bench_blind.c: camera-like cubes without simulator keywords,
 * its own matrix and report).  Any of --scenes, --sizes, --frames,
 * --photons, --methods, --projections, --r2-px, --ref, --target-error,
 * --skips replaces the preset's main sweep by one sweep built from the
 * preset's lists with those replaced.  Method auto is measured once per
 * target error. */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include <glib/gstdio.h>

#include "bench_blind.h"
#include "bench_mpi.h"
#include "bench_scaling.h"
#include "bench_cli.h"
#include "bench_ctx.h"
#include "outfile.h"
#include "pipeline/pipeline.h"
#include "tsm/tsm.h"


/* One Cartesian sweep, in the option syntax. */
typedef struct sweep {
    const char *scenes, *sizes, *frames, *photons, *methods, *projections;
    const char *r2, *ref;
    int block;
    const char *seps, *dms;   /* binary geometry; NULL: "6", "1" */
    const char *targets;      /* auto's target errors; NULL: "0.1" */
    const char *skips;        /* skip sets "a,b/c/none"; NULL: default */
} sweep;

static const sweep quick_sweeps[] = {
    {"binary,six-star", "128", "50", "0", "direct,tsm,tsm-fourier", "18,180",
     "0", "both", 0, NULL, NULL, NULL, NULL},
};

static const sweep speed_sweeps[] = {
    {"binary", "200", "100", "0", "direct,tsm,tsm-fourier", "18,180", "28",
     "no", 0, NULL, NULL, NULL, NULL},
};

static const sweep default_sweeps[] = {
    {"binary,six-star,extended", "128", "100", "0,1000",
     "direct,tsm,tsm-fourier", "6,18,36,90,180,360", "8,16,28", "both", 0, NULL, NULL, NULL, NULL},
    /* Scaling: size (TSM to 512^2; direct's dense R2 = 0.14 N grows as
     * N^4, so it stops at 256^2), then frame count. */
    {"binary", "64,128,256,512", "100", "0", "tsm-fourier", "180", "0", "no", 3, NULL, NULL, NULL, NULL},
    {"binary", "64,128,256", "100", "0", "direct", "180", "0", "no", 3, NULL, NULL, NULL, NULL},
    {"binary", "128", "10,30,100,300,1000", "0", "direct,tsm-fourier", "180",
     "0", "no", 3, NULL, NULL, NULL, NULL},
};

typedef bcli_config config;
typedef bcli_ctx ctx;


/* ---- option lists ---- */

static gchar **split(const char *s) { return g_strsplit(s, ",", -1); }

/* Configurations: direct x R2, TSM variants x projections, auto x target
 * errors; each x skip sets, without and/or with the reference. */
static int parse_configs(const sweep *sw, GArray *out)
{
    GArray *proj = g_array_new(FALSE, FALSE, sizeof(int));
    GArray *r2 = g_array_new(FALSE, FALSE, sizeof(int));
    GArray *tg = g_array_new(FALSE, FALSE, sizeof(double));
    GArray *sk = g_array_new(FALSE, FALSE, sizeof(int));
    gchar **m = split(sw->methods);
    int rc = bcli_parse_ints("projections", sw->projections, 2, 3600, proj);
    if (!rc)
        rc = bcli_parse_ints("r2-px", sw->r2, 0, 144, r2);
    if (!rc)
        rc = bcli_parse_doubles("target-error", sw->targets ? sw->targets : "0.1", tg);
    if (!rc)
        rc = bcli_parse_skip_sets(sw->skips, sk);
    int refs[2], nref = 0;
    if (!strcmp(sw->ref, "no") || !strcmp(sw->ref, "both"))
        refs[nref++] = 0;
    if (!strcmp(sw->ref, "yes") || !strcmp(sw->ref, "both"))
        refs[nref++] = 1;
    if (!rc && nref == 0) {
        fprintf(stderr, "specklab bench: --ref '%s': no, yes or both\n", sw->ref);
        rc = 2;
    }
    for (int i = 0; m[i] && !rc; i++) {
        int meth;
        if (pipeline_method_parse(m[i], &meth) != SL_OK) {
            fprintf(stderr, "specklab bench: unknown method '%s' (direct, tsm, "
                    "tsm-fourier, auto)\n", m[i]);
            rc = 2;
            break;
        }
        int np = meth == PIPE_DIRECT ? (int)r2->len
               : meth == PIPE_AUTO ? (int)tg->len : (int)proj->len;
        for (int r = 0; r < nref; r++)
            for (guint q = 0; q < sk->len; q++)
                for (int k = 0; k < np; k++) {
                    config c = {meth, 0, refs[r], g_array_index(sk, int, q), 0, 0};
                    if (meth == PIPE_AUTO)
                        c.target = g_array_index(tg, double, k);
                    else
                        c.param = g_array_index(meth == PIPE_DIRECT ? r2 : proj, int, k);
                    g_array_append_val(out, c);
                }
    }
    g_strfreev(m);
    g_array_free(proj, TRUE);
    g_array_free(r2, TRUE);
    g_array_free(tg, TRUE);
    g_array_free(sk, TRUE);
    return rc;
}

static int run_sweep(ctx *c, const sweep *sw)
{
    GArray *sizes = g_array_new(FALSE, FALSE, sizeof(int));
    GArray *frames = g_array_new(FALSE, FALSE, sizeof(int));
    GArray *photons = g_array_new(FALSE, FALSE, sizeof(double));
    GArray *cfs = g_array_new(FALSE, FALSE, sizeof(config));
    GArray *seps = g_array_new(FALSE, FALSE, sizeof(double));
    GArray *dms = g_array_new(FALSE, FALSE, sizeof(double));
    gchar **scenes = split(sw->scenes);
    int rc = bcli_parse_sizes(sw->sizes, sizes);
    if (!rc)
        rc = bcli_parse_doubles("seps-lod", sw->seps ? sw->seps : "6", seps);
    if (!rc)
        rc = bcli_parse_doubles("dms-mag", sw->dms ? sw->dms : "1", dms);
    if (!rc)
        rc = bcli_parse_ints("frames", sw->frames, 1, 100000, frames);
    if (!rc)
        rc = bcli_parse_doubles("photons", sw->photons, photons);
    if (!rc)
        rc = parse_configs(sw, cfs);
    for (int s = 0; scenes[s] && !rc; s++)
        for (guint z = 0; z + 1 < sizes->len && !rc; z += 2)
            for (guint f = 0; f < frames->len && !rc; f++)
                for (guint p = 0; p < photons->len && !rc; p++)
                    for (guint q = 0; q < seps->len * dms->len && !rc; q++) {
                        int bin = !strcmp(scenes[s], "binary");
                        if (!bin && q > 0)
                            break; /* geometry only varies binaries */
                        bench_sim d;
                        bench_sim_defaults(&d);
                        d.scene = scenes[s];
                        d.width = g_array_index(sizes, int, z);
                        d.height = g_array_index(sizes, int, z + 1);
                        d.nframes = g_array_index(frames, int, f);
                        d.photons = g_array_index(photons, double, p);
                        d.sep_lod = g_array_index(seps, double, q / dms->len);
                        d.dm_mag = g_array_index(dms, double, q % dms->len);
                        d.seed = (uint64_t)c->a->seed;
                        rc = bcli_run_dataset(c, &d, (config *)(void *)cfs->data,
                                         (int)cfs->len, sw->block);
                    }
    g_strfreev(scenes);
    g_array_free(seps, TRUE);
    g_array_free(dms, TRUE);
    g_array_free(sizes, TRUE);
    g_array_free(frames, TRUE);
    g_array_free(photons, TRUE);
    g_array_free(cfs, TRUE);
    return rc;
}

/* The paper's Table 2 (six-star, extended; direct, TSM 180, TSM 18, and
 * our Fourier-slice TSM, at 18 angles also with the iterative inverse) at 200^2 and 128^2 (or --sizes), then binaries at
 * the first size: separations 5..20 lambda/D, dm 0..2. */
static int run_paper(ctx *c)
{
    static const config t2[] = {
        {PIPE_DIRECT, 0, 0, -1, 0, 0}, {PIPE_TSM, 180, 0, -1, 0, 0}, {PIPE_TSM, 18, 0, -1, 0, 0},
        {PIPE_TSM_FOURIER, 180, 0, -1, 0, 0}, {PIPE_TSM_FOURIER, 18, 0, -1, 0, 0},
        {PIPE_TSM_FOURIER, 18, 0, -1, 0, TSM_INV_ITER},
        {PIPE_DIRECT, 0, 1, -1, 0, 0}, {PIPE_TSM, 180, 1, -1, 0, 0}, {PIPE_TSM, 18, 1, -1, 0, 0},
        {PIPE_TSM_FOURIER, 180, 1, -1, 0, 0}, {PIPE_TSM_FOURIER, 18, 1, -1, 0, 0},
        {PIPE_TSM_FOURIER, 18, 1, -1, 0, TSM_INV_ITER}};
    static const char *const scenes[] = {"six-star", "extended"};
    GArray *sizes = g_array_new(FALSE, FALSE, sizeof(int));
    int rc = bcli_parse_sizes(c->a->sizes ? c->a->sizes : "200,128", sizes);
    for (guint z = 0; z + 1 < sizes->len && !rc; z += 2)
        for (int s = 0; s < 2 && !rc; s++) {
            bench_sim d;
            bench_sim_defaults(&d);
            d.scene = scenes[s];
            d.width = g_array_index(sizes, int, z);
            d.height = g_array_index(sizes, int, z + 1);
            d.seed = (uint64_t)c->a->seed;
            rc = bcli_run_dataset(c, &d, t2, (int)(sizeof t2 / sizeof t2[0]), 1);
        }
    static const config bin[] = {
        {PIPE_DIRECT, 0, 0, -1, 0, 0}, {PIPE_TSM, 180, 0, -1, 0, 0}, {PIPE_TSM, 18, 0, -1, 0, 0},
        {PIPE_TSM_FOURIER, 180, 0, -1, 0, 0},
        {PIPE_DIRECT, 0, 1, -1, 0, 0}, {PIPE_TSM, 180, 1, -1, 0, 0}, {PIPE_TSM, 18, 1, -1, 0, 0},
        {PIPE_TSM_FOURIER, 180, 1, -1, 0, 0}};
    static const double seps[] = {5, 10, 15, 20}, dms[] = {0, 1, 2};
    for (int i = 0; i < 4 && !rc && sizes->len >= 2; i++)
        for (int j = 0; j < 3 && !rc; j++) {
            bench_sim d;
            bench_sim_defaults(&d);
            d.width = g_array_index(sizes, int, 0);
            d.height = g_array_index(sizes, int, 1);
            d.sep_lod = seps[i];
            d.dm_mag = dms[j];
            d.pa_deg = 30 + 25 * (3 * i + j); /* spread PAs over the circle */
            d.seed = (uint64_t)c->a->seed + 1 + (uint64_t)(3 * i + j);
            rc = bcli_run_dataset(c, &d, bin, 8, 2);
        }
    g_array_free(sizes, TRUE);
    return rc;
}

static int selection_given(const bench_args *a)
{
    return a->scenes || a->sizes || a->frames || a->photons || a->methods ||
           a->projections || a->r2 || a->ref || a->seps || a->dms ||
           a->targets || a->skips;
}

static int run_all(ctx *c)
{
    const bench_args *a = c->a;
    if (a->paper)
        return run_paper(c);
    if (a->skips_report)
        return bcli_run_skips(c);
    const sweep *list = a->quick ? quick_sweeps : a->speed ? speed_sweeps
                                                           : default_sweeps;
    int n = a->quick ? (int)G_N_ELEMENTS(quick_sweeps)
          : a->speed ? (int)G_N_ELEMENTS(speed_sweeps)
                     : (int)G_N_ELEMENTS(default_sweeps);
    if (selection_given(a)) {
        sweep one = list[0];
        one.scenes = a->scenes ? a->scenes : one.scenes;
        one.sizes = a->sizes ? a->sizes : one.sizes;
        one.frames = a->frames ? a->frames : one.frames;
        one.photons = a->photons ? a->photons : one.photons;
        one.methods = a->methods ? a->methods : one.methods;
        one.projections = a->projections ? a->projections : one.projections;
        one.r2 = a->r2 ? a->r2 : one.r2;
        one.ref = a->ref ? a->ref : one.ref;
        one.seps = a->seps ? a->seps : one.seps;
        one.dms = a->dms ? a->dms : one.dms;
        one.targets = a->targets ? a->targets : one.targets;
        one.skips = a->skips ? a->skips : one.skips;
        return run_sweep(c, &one);
    }
    int rc = 0;
    for (int i = 0; i < n && !rc; i++)
        rc = run_sweep(c, &list[i]);
    return rc;
}

static void cleanup(ctx *c)
{
    for (guint i = 0; i < c->refs->len; i++) {
        refset *r = &g_array_index(c->refs, refset, i);
        if (!c->a->keep_data) {
            g_unlink(r->cube);
            g_unlink(r->psf);
        }
        g_free(r->cube);
        g_free(r->psf);
    }
    if (!c->a->keep_data)
        g_rmdir(c->dir);
}

static const char *csv_path(const bench_args *a) { return a->csv ? a->csv : "bench.csv"; }
static const char *png_path(const bench_args *a) { return a->png ? a->png : "bench.png"; }
static const char *md_path(const bench_args *a) { return a->md ? a->md : "none"; }

/* The CSV, the chart and the Markdown table follow outfile.h: checked
 * before anything runs (a refusal after minutes of measuring would waste
 * them), then written through a temporary (write_outputs). */
static int outputs_ok(const bench_args *a)
{
    const char *path[] = {csv_path(a), png_path(a), md_path(a)};
    for (int i = 0; i < 3; i++) {
        GError *ge = NULL;
        if (strcmp(path[i], "none") && !outfile_check(path[i], a->overwrite, NULL, 0, &ge)) {
            fprintf(stderr, "specklab bench: %s\n", ge->message);
            g_error_free(ge);
            return 0;
        }
        for (int k = 0; k < i; k++)
            if (strcmp(path[i], "none") && !strcmp(path[i], path[k])) {
                fprintf(stderr, "specklab bench: %s is named for two outputs\n", path[i]);
                return 0;
            }
    }
    return 1;
}

/* 0, or 1 after a message. */
static int write_outputs(const bench_args *a, GArray *rows, double base_rss_mb)
{
    const char *path[] = {csv_path(a), png_path(a), md_path(a)};
    int bad = 0;
    for (int i = 0; i < 3; i++) {
        if (!strcmp(path[i], "none"))
            continue;
        outfile f;
        GError *ge = NULL;
        if (!outfile_begin(&f, path[i], a->overwrite, NULL, 0, &ge)) {
            fprintf(stderr, "specklab bench: %s\n", ge->message);
            g_error_free(ge);
            bad = 1;
            continue;
        }
        int rc = i == 0 ? bcli_write_csv(f.tmp, rows, base_rss_mb)
               : i == 1 ? bcli_write_png(f.tmp, rows)
                        : bcli_write_md(f.tmp, rows, a->command);
        /* the chart writes nothing when no data set has 3 points */
        int wrote = rc == 0 && g_file_test(f.tmp, G_FILE_TEST_EXISTS);
        if (wrote && !outfile_commit(&f, &ge)) {
            fprintf(stderr, "specklab bench: %s\n", ge->message);
            g_error_free(ge);
            rc = 1;
        } else if (wrote) {
            fprintf(stderr, "bench: wrote %s\n", path[i]);
        }
        outfile_clear(&f);
        bad |= rc != 0;
    }
    return bad;
}

static int bench_main(bench_args *a)
{
    if (!outputs_ok(a))
        return 2;
    ctx c = {a, NULL, NULL, NULL, 0, 0};
    GError *gerr = NULL;
    if (a->dir) {
        if (g_mkdir_with_parents(a->dir, 0755) != 0) {
            fprintf(stderr, "specklab bench: cannot create %s: %s\n", a->dir,
                    g_strerror(errno));
            return 1;
        }
        c.dir = g_strdup(a->dir);
        a->keep_data = TRUE;
    } else if (!(c.dir = g_dir_make_tmp("specklab-bench-XXXXXX", &gerr))) {
        fprintf(stderr, "specklab bench: %s\n", gerr->message);
        g_error_free(gerr);
        return 1;
    }
    c.rows = g_array_new(FALSE, FALSE, sizeof(bcli_row));
    c.refs = g_array_new(FALSE, FALSE, sizeof(refset));
    double base = bench_baseline_rss_mb();
    printf("# specklab bench: %s preset, %d run(s) per point (median), "
           "FFTW_%s, 17-hole mask, r0 0.2 m, wind 10 m/s, 500 nm, Nyquist\n"
           "# time: wall/CPU of pipeline_run on the FITS file; rss: the "
           "child's peak (fork floor %.1f MB)\n", a->paper ? "paper" :
           a->quick ? "quick" : a->speed ? "speed" : a->skips_report ? "skips" :
           "default", a->repeat,
           a->estimate ? "ESTIMATE" : "MEASURE", base);
    bcli_print_header();
    int out = 0, rc = run_all(&c);
    if (rc == 2) /* an option that does not parse: nothing ran, write nothing */
        goto done;
    bcli_mark_fronts(c.rows);
    bcli_print_fronts(c.rows);
    bcli_print_scaling(c.rows);
    if (a->paper)
        bcli_print_paper(c.rows);
    if (a->speed)
        bcli_print_targets(c.rows);
    bcli_print_auto(c.rows);
    if (a->skips_report)
        bcli_print_skips(c.rows);
    fflush(stdout);
    out = write_outputs(a, c.rows, base);
    if (a->catalog && bcli_write_catalog(a->catalog, c.rows, base))
        out = 1;
    if (c.failures)
        fprintf(stderr, "specklab bench: %d point(s) failed (see the table)\n",
                c.failures);
done:
    cleanup(&c);
    g_array_free(c.rows, TRUE);
    g_array_free(c.refs, TRUE);
    g_free(c.dir);
    return rc ? rc : out || c.failures ? 1 : 0;
}

/* --blind: its own matrix (bench_blind.h); the sweep options do not apply. */
static int run_blind(const bench_args *a)
{
    blind_opts o = {a->quick, a->csv, a->dir, a->methods, a->conditions,
                    a->targets, a->repeat, a->threads, a->estimate,
                    (uint64_t)a->seed,
                    a->paper || a->speed || a->skips_report || a->scenes ||
                    a->sizes || a->frames || a->photons || a->projections ||
                    a->r2 || a->seps || a->dms || a->ref || a->skips ||
                    a->catalog || a->png || a->md || a->interval_ms > 0,
                    a->overwrite};
    return blind_run(&o);
}

/* "specklab bench ARGS" as typed (GOption reorders argv: taken before
 * parsing), arguments quoted for the shell where they need it. */
static char *command_line(int argc, char **argv)
{
    GString *s = g_string_new("specklab bench");
    for (int i = 1; i < argc; i++) {
        const char *v = argv[i];
        gboolean plain = *v != 0;
        for (const char *p = v; *p && plain; p++)
            plain = g_ascii_isalnum(*p) || strchr("-_.,/=:+@%", *p);
        char *q = plain ? g_strdup(v) : g_shell_quote(v);
        g_string_append_printf(s, " %s", q);
        g_free(q);
    }
    return g_string_free(s, FALSE);
}

int cmd_bench(int argc, char **argv)
{
    bench_args a;
    memset(&a, 0, sizeof a);
    a.seed = 1;
    GOptionEntry entries[] = {
        {"quick", 0, 0, G_OPTION_ARG_NONE, &a.quick, "a handful of points (< 1 min; make bench)", NULL},
        {"paper", 0, 0, G_OPTION_ARG_NONE, &a.paper, "the paper's Table 2 layout and a binaries table", NULL},
        {"speed", 0, 0, G_OPTION_ARG_NONE, &a.speed, "the speed targets (200^2, 100 frames, 5 runs; docs/results.md)", NULL},
        {"skips-report", 0, 0, G_OPTION_ARG_NONE, &a.skips_report, "each skip on/off and auto against fixed TSM-180 (200^2, 100 frames)", NULL},
        {"scenes", 0, 0, G_OPTION_ARG_STRING, &a.scenes, "binary,six-star,extended", "LIST"},
        {"sizes", 0, 0, G_OPTION_ARG_STRING, &a.sizes, "frame sizes, N or WxH (e.g. 64,128,200; --paper: 200,128)", "LIST"},
        {"frames", 0, 0, G_OPTION_ARG_STRING, &a.frames, "frame counts (e.g. 10,100,1000)", "LIST"},
        {"photons", 0, 0, G_OPTION_ARG_STRING, &a.photons, "photons per frame, 0 = noiseless (e.g. 0,1000)", "LIST"},
        {"methods", 0, 0, G_OPTION_ARG_STRING, &a.methods, "direct,tsm,tsm-fourier,auto", "LIST"},
        {"target-error", 0, 0, G_OPTION_ARG_STRING, &a.targets, "auto's target errors 1 - c (default 0.1; e.g. 0.06,0.1,0.2)", "LIST"},
        {"skips", 0, 0, G_OPTION_ARG_STRING, &a.skips, "skip sets, / between sets (e.g. none/crop/all; default: all for auto, none otherwise)", "SETS"},
        {"projections", 0, 0, G_OPTION_ARG_STRING, &a.projections, "TSM projection counts (e.g. 6,18,180,360)", "LIST"},
        {"r2-px", 0, 0, G_OPTION_ARG_STRING, &a.r2, "direct |u2| radii in px, 0 = 0.14 N (e.g. 8,16,28)", "LIST"},
        {"seps-lod", 0, 0, G_OPTION_ARG_STRING, &a.seps, "binary separations in lambda/D (LOD), D = mask extent (default 6)", "LIST"},
        {"dms-mag", 0, 0, G_OPTION_ARG_STRING, &a.dms, "binary magnitude differences (default 1)", "LIST"},
        {"ref", 0, 0, G_OPTION_ARG_STRING, &a.ref, "reference variants: no, yes or both", "MODE"},
        {"repeat", 0, 0, G_OPTION_ARG_INT, &a.repeat, "runs per point, median reported (default 1; --speed 5)", "N"},
        {"threads", 0, 0, G_OPTION_ARG_INT, &a.threads, "threads (direct: default 2; tsm: online CPUs, at most 4)", "N"},
        {"seed", 0, 0, G_OPTION_ARG_INT64, &a.seed, "simulation seed (reference: seed + 1000)", "N"},
        {"frame-interval-ms", 0, 0, G_OPTION_ARG_DOUBLE, &a.interval_ms, "time between simulated frames (default 10: 100 frames share 10 m of screen)", "MS"},
        {"estimate", 0, 0, G_OPTION_ARG_NONE, &a.estimate, "FFTW_ESTIMATE plans instead of FFTW_MEASURE", NULL},
        {"csv", 0, 0, G_OPTION_ARG_FILENAME, &a.csv, "CSV output (default bench.csv; none: skip)", "FILE"},
        {"overwrite", 0, 0, G_OPTION_ARG_NONE, &a.overwrite, "replace an existing CSV, chart or Markdown table", NULL},
        {"png", 0, 0, G_OPTION_ARG_FILENAME, &a.png, "time/error chart (default bench.png; none: skip)", "FILE"},
        {"md", 0, 0, G_OPTION_ARG_FILENAME, &a.md, "also the table as Markdown, headed by this command (default: none)", "FILE"},
        {"catalog", 0, 0, G_OPTION_ARG_FILENAME, &a.catalog, "also add rows to this catalogue's benchmarks table", "DB"},
        {"data-dir", 0, 0, G_OPTION_ARG_FILENAME, &a.dir, "simulate into DIR and keep the cubes (default: a temporary directory)", "DIR"},
        {"blind", 0, 0, G_OPTION_ARG_NONE, &a.blind, "camera-like blind cubes, one factor at a time, default options (with --quick: 4 conditions, < 1 min; CSV default out/bench/blind.csv)", NULL},
        {"conditions", 0, 0, G_OPTION_ARG_STRING, &a.conditions, "--blind: only these conditions (e.g. baseline,hot-50)", "LIST"},
        {"mpi", 0, 0, G_OPTION_ARG_NONE, &a.mpi, "specklab-mpi recon on 1, 2 and 4 ranks (oversubscribed): time, parallel efficiency, and a model for N nodes (bytes of sums reduced per run against the network's bandwidth); --methods, --sizes, --frames, --repeat, --threads (per rank, default 1) apply", NULL},
        {"scaling", 0, 0, G_OPTION_ARG_NONE, &a.scaling, "direct, tsm and tsm-fourier at 1, 2, 4 ... threads: wall time per stage (open, plan, read, frame, accum, solve, measure), speedup and parallel fraction; --sizes, --frames, --methods, --repeat, --estimate apply (default 200^2 x 100)", NULL},
        {NULL, 0, 0, 0, NULL, NULL, NULL}};
    GOptionContext *ctx_ = g_option_context_new("- run time against error on simulated cubes");
    g_option_context_add_main_entries(ctx_, entries, NULL);
    g_option_context_set_description(ctx_,
        "Each point: pipeline_run end to end from a FITS cube, in a forked child\n"
        "(wall and CPU time, the child's peak RSS), scored against the simulation's\n"
        "cophased image: 1 - c, 1 - c high-passed (Gaussian sigma 2 px subtracted),\n"
        "and for binaries the separation, PA and dm errors.  'ref' points use a\n"
        "point-source sequence (seed + 1000) and its cophased image as --target.\n"
        "Any selection option replaces the preset's sweeps by one sweep.");
    int status = 2;
    a.command = command_line(argc, argv);
    if (!cli_parse(ctx_, &argc, &argv))
        goto free_ctx;
    if (argc > 1) {
        fprintf(stderr, "specklab bench: unexpected argument '%s'\n", argv[1]);
        goto free_ctx;
    }
    if (a.repeat == 0)
        a.repeat = a.speed ? 5 : 1;
    if (a.repeat < 1 || a.repeat > BENCH_MAX_REPEAT || a.threads < 0 ||
        !(a.interval_ms >= 0 && a.interval_ms <= 1e4) ||
        a.quick + a.paper + a.speed + a.skips_report > 1) {
        fprintf(stderr, "specklab bench: --repeat 1..%d, --threads >= 0, "
                "--frame-interval-ms 0..10000, and at most one of "
                "--quick/--paper/--speed/--skips-report\n", BENCH_MAX_REPEAT);
        goto free_ctx;
    }
    if (a.conditions && !a.blind) {
        fprintf(stderr, "specklab bench: --conditions needs --blind\n");
        goto free_ctx;
    }
    status = a.mpi ? bench_mpi_run(&a) : a.scaling ? bench_scaling_run(&a)
           : a.blind ? run_blind(&a) : bench_main(&a);
free_ctx:
    g_option_context_free(ctx_);
    g_free(a.scenes); g_free(a.sizes); g_free(a.frames); g_free(a.photons);
    g_free(a.methods); g_free(a.projections); g_free(a.r2); g_free(a.ref);
    g_free(a.seps); g_free(a.dms); g_free(a.targets); g_free(a.skips);
    g_free(a.csv); g_free(a.png); g_free(a.catalog); g_free(a.dir);
    g_free(a.conditions); g_free(a.md); g_free(a.command);
    return status;
}
