/* bench_blind.c - `specklab bench --blind`'s matrix and runner (see
 * bench_blind.h). */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <glib/gstdio.h>

#include "bench_blind.h"
#include "outfile.h"
#include "sim/sim_file.h"
#include "pipeline/pipeline.h"
#include "sim/sim.h"

#define DEFAULT_METHODS "direct,tsm-fourier,tsm,auto"

/* ---- the matrix ---- */

/* 100 ADU of a 12-bit range, scaled with the converter's range. */
static double bias_for_bits(int bits)
{
    return round(100.0 * (ldexp(1, bits) - 1) / 4095.0);
}

static void baseline(bench_sim *s, uint64_t seed)
{
    bench_sim_defaults(s);
    s->scene = "binary";
    s->width = s->height = 128;
    s->nframes = 100;
    s->sep_lod = 6;
    s->pa_deg = 57;
    s->dm_mag = 1;
    s->photons = 2e4;
    s->gain_e_per_adu = 2;
    s->read_noise_e = 3;
    s->bias_adu = bias_for_bits(12);
    s->adc_bits = 12;
    s->r0_m = 0.2;
    s->mask = "nrm17";
    s->phase_model = SIM_PHASE_SCREEN;
    s->sampling_nyq = 1;
    s->seed = seed;
    s->blind = 1;
}

/* No detector at all: frames in relative flux. */
static void noiseless(bench_sim *s)
{
    s->photons = 0;
    s->gain_e_per_adu = s->read_noise_e = s->bias_adu = 0;
    s->adc_bits = s->hot_pixels = s->dead_pixels = 0;
}

/* Offset d px along (0.8, -0.6): both axes move, |offset| = d. */
static void offset(bench_sim *s, double d_px, double jitter_px)
{
    s->offset_x_px = 0.8 * d_px;
    s->offset_y_px = -0.6 * d_px;
    s->jitter_px = jitter_px;
}

static void adc(bench_sim *s, int bits)
{
    s->adc_bits = bits;
    s->bias_adu = bias_for_bits(bits);
}

/* A filled 0.35 m telescope with a 30 % obstruction at 550 nm, 0.18"/px
 * (Nyquist is 0.162"), r0 0.08 m, 40 frames of 7 ms, 8 bits, a 0.32"
 * binary (about 1 lambda/D) of dm 0.6. */
static void amateur(bench_sim *s)
{
    s->mask = "full";
    s->aperture_m = 0.35;
    s->obstruction = 0.3;
    s->wavelength_m = 550e-9;
    s->sampling_nyq = 0;
    s->plate_scale_arcsec = 0.18;
    s->r0_m = 0.08;
    s->nframes = 40;
    s->frame_interval_s = s->exposure_s = 0.007;
    s->sep_arcsec = 0.32;
    s->dm_mag = 0.6;
    s->photons = 1e5;
    adc(s, 8);
}

typedef struct mlist {
    blind_cond *out;
    int n, max, quick_only;
} mlist;

static void add(mlist *m, const char *name, int quick, const bench_sim *s)
{
    if (m->n >= m->max || (m->quick_only && !quick))
        return;
    blind_cond *c = &m->out[m->n++];
    snprintf(c->name, sizeof c->name, "%s", name);
    c->quick = quick;
    c->sim = *s;
}

/* The one-factor-at-a-time variations of b. */
static void one_factor(mlist *m, const bench_sim *b)
{
    static const double samp[] = {0.5, 2}, phot[] = {1e3, 1e4, 1e5, 1e6};
    static const double rn[] = {0, 10};
    static const int bits[] = {8, 16}, hot[] = {10, 50}, frames[] = {40, 400};
    static const int offs[] = {0, 16, 32};
    static const char *const phot_name[] = {"1e3", "1e4", "1e5", "1e6"};
    char name[BLIND_NAME_MAX];
    bench_sim s = *b;
    s.mask = "full";
    add(m, "mask-full", 0, &s);
    s = *b;
    s.phase_model = SIM_PHASE_PISTON;
    add(m, "phase-piston", 0, &s);
    for (int i = 0; i < 2; i++) {
        s = *b;
        s.sampling_nyq = samp[i];
        snprintf(name, sizeof name, "sampling-%gx", samp[i]);
        add(m, name, 0, &s);
    }
    for (int i = 0; i < 4; i++) {
        s = *b;
        s.photons = phot[i];
        snprintf(name, sizeof name, "photons-%s", phot_name[i]);
        add(m, name, 0, &s);
    }
    for (int i = 0; i < 2; i++) {
        s = *b;
        s.read_noise_e = rn[i];
        snprintf(name, sizeof name, "read-noise-%g", rn[i]);
        add(m, name, 0, &s);
    }
    for (int i = 0; i < 2; i++) {
        s = *b;
        adc(&s, bits[i]);
        snprintf(name, sizeof name, "adc-%d", bits[i]);
        add(m, name, 0, &s);
    }
    for (int i = 0; i < 2; i++) {
        s = *b;
        s.hot_pixels = hot[i];
        snprintf(name, sizeof name, "hot-%d", hot[i]);
        add(m, name, 0, &s);
    }
    for (int i = 0; i < 3; i++) {
        s = *b;
        offset(&s, offs[i], 2);
        snprintf(name, sizeof name, "offset-%d+jit2", offs[i]);
        add(m, name, 0, &s);
    }
    for (int i = 0; i < 2; i++) {
        s = *b;
        s.nframes = frames[i];
        snprintf(name, sizeof name, "frames-%d", frames[i]);
        add(m, name, 0, &s);
    }
}

int blind_matrix(int quick, uint64_t seed, blind_cond *out, int max)
{
    mlist m = {out, 0, max, quick};
    bench_sim b, s;
    baseline(&b, seed);
    add(&m, "baseline", 1, &b);
    one_factor(&m, &b);
    for (int piston = 0; piston < 2; piston++) {
        s = b;
        s.scene = "six-star";
        s.phase_model = piston ? SIM_PHASE_PISTON : SIM_PHASE_SCREEN;
        noiseless(&s);
        add(&m, piston ? "six-star-piston" : "six-star-screen", piston, &s);
    }
    s = b;
    s.hot_pixels = 10;
    offset(&s, 32, 2);
    add(&m, "hot10+offset32", 1, &s);
    s = b;
    s.mask = "full";
    adc(&s, 8);
    add(&m, "full+adc8", 1, &s);
    /* 8 bits bind only when the gain must rise: at the baseline's 2e4
     * photons the brightest pixel holds ~160 e-, 80 codes at 2 e-/ADU. */
    s = b;
    s.photons = 1e6;
    adc(&s, 8);
    add(&m, "photons-1e6+adc8", 0, &s);
    s = b;
    s.photons = 1e4;
    s.read_noise_e = 10;
    adc(&s, 8);
    s.hot_pixels = s.dead_pixels = 10;
    offset(&s, 16, 2);
    s.nframes = 40;
    add(&m, "camera-worst", 0, &s);
    s = b;
    amateur(&s);
    add(&m, "amateur", 0, &s);
    return m.n;
}

/* ---- running ---- */

typedef struct blind_ctx {
    const blind_opts *o;
    char *dir;
    int methods[4], nmethods;
    double target;          /* auto's target 1 - c; 0: the default */
    GArray *rows;           /* blind_row */
} blind_ctx;

static int parse_methods(const char *list, int *out, int *n)
{
    gchar **v = g_strsplit(list, ",", -1);
    int rc = 0;
    *n = 0;
    for (int i = 0; v[i] && !rc; i++) {
        int m;
        if (pipeline_method_parse(v[i], &m) != SL_OK || *n >= 4) {
            fprintf(stderr, "specklab bench: --blind --methods '%s': expected "
                    "up to four of direct, tsm, tsm-fourier, auto\n", v[i]);
            rc = 2;
        } else {
            out[(*n)++] = m;
        }
    }
    g_strfreev(v);
    if (!rc && *n == 0) {
        fprintf(stderr, "specklab bench: --blind --methods: no method given\n");
        rc = 2;
    }
    return rc;
}

static int listed(gchar **v, const char *name)
{
    for (int i = 0; v[i]; i++)
        if (!strcmp(v[i], name))
            return 1;
    return 0;
}

/* Keep only the conditions named in list (comma-separated), in the
 * matrix's order. */
static int select_conditions(const char *list, blind_cond *c, int *n)
{
    gchar **v = g_strsplit(list, ",", -1);
    int rc = 0, kept = 0;
    for (int i = 0; v[i] && !rc; i++) {
        int hit = 0;
        for (int k = 0; k < *n && !hit; k++)
            hit = !strcmp(v[i], c[k].name);
        if (!hit) {
            fprintf(stderr, "specklab bench: --conditions '%s': not in the "
                    "matrix; it has:", v[i]);
            for (int k = 0; k < *n; k++)
                fprintf(stderr, " %s", c[k].name);
            fprintf(stderr, "\n");
            rc = 2;
        }
    }
    for (int k = 0; k < *n && !rc; k++)
        if (listed(v, c[k].name))
            c[kept++] = c[k];
    g_strfreev(v);
    if (!rc)
        *n = kept;
    return rc;
}

static void row_init(blind_row *r, const blind_cond *cd, const bench_sim *d,
                     double peak_adu, const bench_truth *t, int method,
                     double target)
{
    memset(r, 0, sizeof *r);
    memcpy(r->cond, cd->name, sizeof r->cond);
    r->sim = *d;
    r->peak_adu = peak_adu;
    r->truth_binary = t && t->binary;
    r->true_sep_px = t ? t->sep_px : NAN;
    r->true_pa_deg = t ? t->pa_deg : NAN;
    r->true_dm_mag = t ? t->dm_mag : NAN;
    r->plate_scale_arcsec = t ? t->plate_scale_arcsec : NAN;
    r->sampling_nyq = t ? t->plate_scale_arcsec / t->nyquist_arcsec : NAN;
    r->method = method;
    r->target = target > 0 ? target : 0.1;
    r->t.wall_s = r->t.pred_error = NAN;
    bench_score_init(&r->s);
    r->dsep_px = r->dpa_deg = r->ddm_mag = NAN;
}

static void measure(blind_ctx *c, blind_row *r, const char *cube,
                    const bench_truth *t, float *img)
{
    const blind_opts *a = c->o;
    pipeline_opts o;
    pipeline_opts_defaults(&o);
    o.method = r->method;
    o.closure_binary = 1;
    o.nthreads = a->threads;
    o.fftw_measure = !a->estimate;
    if (c->target > 0)
        o.target_error = c->target;
    sl_err e = {0};
    r->status = bench_measure(cube, &o, a->repeat, img, t->width, t->height,
                              &r->t, &e);
    if (r->status == SL_OK)
        r->status = bench_score_image(img, t, BENCH_HP_SIGMA_PX, &r->s, &e);
    if (r->status != SL_OK) {
        snprintf(r->msg, sizeof r->msg, "%s", e.msg);
        return;
    }
    if (bench_verdict_errors(&r->t.binary, t, &r->dsep_px, &r->dpa_deg,
                             &r->ddm_mag))
        r->within = fabs(r->dsep_px) <= BLIND_SEP_TOL_PX &&
                    fabs(r->dpa_deg) <= BLIND_PA_TOL_DEG &&
                    fabs(r->ddm_mag) <= BLIND_DM_TOL_MAG;
    r->oriented = r->within && r->t.binary.status == PIPE_BIN_MEASURED;
}

static void remove_data(const char *cube)
{
    char *side = sim_file_sidecar_path(cube);
    g_unlink(cube);
    if (side)
        g_unlink(side);
    free(side);
}

/* Simulate cd (gain fitted, blind), read its truth back from the sidecar,
 * then one row per method; a simulation that fails gives failed rows. */
static void run_condition(blind_ctx *c, const blind_cond *cd)
{
    bench_sim d = cd->sim;
    d.blind = 1;
    double peak = NAN;
    char *cube = g_strdup_printf("%s/%s.fits", c->dir, cd->name);
    sl_err e = {0};
    bench_truth t = {0};
    float *img = malloc(sizeof(float) * (size_t)d.width * (size_t)d.height);
    fprintf(stderr, "bench: simulating %s\n", cd->name);
    int rc = !img ? sl_seterr(&e, SL_ENOMEM, "out of memory")
                  : bench_sim_fit_gain(&d, BLIND_PEAK_FILL, &peak, &e);
    if (rc == SL_OK)
        rc = bench_sim_write(&d, cube, NULL, &e);
    if (rc == SL_OK)
        rc = bench_truth_read_sidecar(&t, cube, &e);
    if (rc == SL_OK && d.photons > 0)
        printf("# %s: gain %.3g e-/ADU, bias %g ADU, brightest pixel ~%.0f ADU "
               "of %.0f\n", cd->name, d.gain_e_per_adu, d.bias_adu, peak,
               d.adc_bits ? ldexp(1, d.adc_bits) - 1 : d.saturation_adu);
    for (int k = 0; k < c->nmethods; k++) {
        blind_row r;
        row_init(&r, cd, &d, peak, rc == SL_OK ? &t : NULL, c->methods[k],
                 c->target);
        if (rc == SL_OK) {
            measure(c, &r, cube, &t, img);
        } else {
            r.status = rc;
            snprintf(r.msg, sizeof r.msg, "simulation: %.400s", e.msg);
        }
        blind_print_row(&r);
        g_array_append_val(c->rows, r);
    }
    bench_truth_clear(&t);
    free(img);
    if (!c->o->dir)
        remove_data(cube);
    g_free(cube);
}

static char *work_dir(const blind_opts *o)
{
    GError *gerr = NULL;
    if (o->dir) {
        if (g_mkdir_with_parents(o->dir, 0755) == 0)
            return g_strdup(o->dir);
        fprintf(stderr, "specklab bench: cannot create %s: %s\n", o->dir,
                g_strerror(errno));
        return NULL;
    }
    char *d = g_dir_make_tmp("specklab-blind-XXXXXX", &gerr);
    if (!d) {
        fprintf(stderr, "specklab bench: %s\n", gerr->message);
        g_error_free(gerr);
    }
    return d;
}

static const char *csv_path(const blind_opts *o)
{
    return o->csv ? o->csv : o->quick ? "out/bench/blind-quick.csv" : "out/bench/blind.csv";
}

/* The CSV by outfile.h's rules, checked before anything runs (a refusal
 * after the matrix would waste it); its directory (out/bench by default)
 * is made when missing.  0, 1 (cannot) or 2 (exists, no --overwrite). */
static int csv_ok(const blind_opts *o)
{
    const char *path = csv_path(o);
    if (!strcmp(path, "none"))
        return 0;
    char *dir = g_path_get_dirname(path);
    int bad = g_mkdir_with_parents(dir, 0755) != 0;
    if (bad)
        fprintf(stderr, "specklab bench: cannot create %s: %s\n", dir, g_strerror(errno));
    g_free(dir);
    GError *ge = NULL;
    if (!bad && !outfile_check(path, o->overwrite, NULL, 0, &ge)) {
        fprintf(stderr, "specklab bench: %s\n", ge->message);
        g_error_free(ge);
        return 2;
    }
    return bad;
}

/* Written through a temporary, renamed over the name when whole. */
static int write_csv(const blind_opts *o, const blind_row *rows, int n)
{
    const char *path = csv_path(o);
    if (!strcmp(path, "none"))
        return 0;
    outfile f;
    GError *ge = NULL;
    int bad = !outfile_begin(&f, path, o->overwrite, NULL, 0, &ge) ||
              blind_write_csv(f.tmp, rows, n) || !outfile_commit(&f, &ge);
    if (ge) {
        fprintf(stderr, "specklab bench: %s\n", ge->message);
        g_error_free(ge);
    }
    outfile_clear(&f);
    if (!bad)
        printf("# wrote %s (%d rows)\n", path, n);
    return bad;
}

/* The options that make sense here; auto's target into *target. */
static int check_options(const blind_opts *o, double *target)
{
    char *end = NULL;
    *target = o->target ? g_ascii_strtod(o->target, &end) : 0;
    if (o->other_options) {
        fprintf(stderr, "specklab bench: --blind runs its own matrix: it takes "
                "--quick, --methods, --conditions, --target-error (one value), "
                "--repeat, --threads, --seed, --estimate, --csv and --data-dir\n");
        return 2;
    }
    if (o->target && (end == o->target || *end || !(*target > 0 && *target < 1))) {
        fprintf(stderr, "specklab bench: --blind --target-error '%s': one number "
                "in (0, 1)\n", o->target);
        return 2;
    }
    return 0;
}

int blind_run(const blind_opts *o)
{
    blind_cond conds[BLIND_MAX_CONDITIONS];
    /* --conditions picks from the whole matrix, --quick or not */
    int ncond = blind_matrix(o->quick && !o->conditions, o->seed, conds,
                             BLIND_MAX_CONDITIONS);
    blind_ctx c = {o, NULL, {0}, 0, 0, NULL};
    int rc;
    if (check_options(o, &c.target) ||
        parse_methods(o->methods ? o->methods : DEFAULT_METHODS, c.methods,
                      &c.nmethods) ||
        (o->conditions && select_conditions(o->conditions, conds, &ncond)))
        return 2;
    if ((rc = csv_ok(o)) != 0)
        return rc;
    if (!(c.dir = work_dir(o)))
        return 1;
    c.rows = g_array_new(FALSE, FALSE, sizeof(blind_row));
    double t0 = cli_now_s();
    printf("# specklab bench --blind%s: %d conditions x %d methods, cubes "
           "written as a camera would (no simulator keywords), truth from "
           "sidecars; default options + closure_binary, FFTW_%s, %d run(s) "
           "per point\n", o->quick ? " --quick" : "", ncond, c.nmethods,
           o->estimate ? "ESTIMATE" : "MEASURE", o->repeat);
    blind_print_header();
    for (int i = 0; i < ncond; i++)
        run_condition(&c, &conds[i]);
    const blind_row *rows = (const blind_row *)(void *)c.rows->data;
    int nrows = (int)c.rows->len;
    blind_print_summary(rows, nrows, c.methods, c.nmethods);
    printf("# total %.1f s\n", cli_now_s() - t0);
    rc = write_csv(o, rows, nrows);
    if (!o->dir)
        g_rmdir(c.dir);
    g_free(c.dir);
    g_array_free(c.rows, TRUE);
    return rc;
}
