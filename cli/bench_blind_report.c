/* bench_blind_report.c - what `specklab bench --blind` prints and writes:
 * the streamed table, the summary and the CSV (see bench_blind.h). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "bench_blind.h"
#include "pipeline/pipeline.h"
#include "sim/sim.h"

static int ok(const blind_row *r) { return r->status == SL_OK; }

/* "auto:direct" for auto rows (what it ran), else the method. */
static void method_label(const blind_row *r, char *buf, size_t n)
{
    const char *m = pipeline_method_name(r->method);
    if (r->method == PIPE_AUTO && r->t.method_run >= 0)
        snprintf(buf, n, "%s:%s", m, pipeline_method_name(r->t.method_run));
    else
        snprintf(buf, n, "%s", m);
}

/* in: within the bounds; in~: within with the PA modulo 180 (ambiguous);
 * out; "-" when the condition has no binary. */
static const char *bounds_label(const blind_row *r)
{
    if (!r->truth_binary)
        return "-";
    return r->oriented ? "in" : r->within ? "in~" : "out";
}

void blind_print_header(void)
{
    printf("# c: against the cophased image; binary: the verdict "
           "(pipeline_result.binary), its errors measured - true, the PA "
           "modulo 180 when ambiguous; bounds %.2f px, %.1f deg, %.2f mag "
           "(in~: only modulo 180); pred: auto's predicted 1 - c\n",
           BLIND_SEP_TOL_PX, BLIND_PA_TOL_DEG, BLIND_DM_TOL_MAG);
    printf("%-16s %-17s %7s  %-12s %7s %7s %7s %-4s | %6s %6s | %7s\n",
           "condition", "method", "c", "binary", "dsep_px", "dPA_deg",
           "ddm_mag", "bnds", "pred", "1-c", "wall_s");
}

static void num(double v, int width, int prec, int sign)
{
    if (isfinite(v))
        printf(sign ? " %+*.*f" : " %*.*f", width, prec, v);
    else
        printf(" %*s", width, "-");
}

void blind_print_row(const blind_row *r)
{
    char m[48];
    method_label(r, m, sizeof m);
    printf("%-16s %-17s", r->cond, m);
    if (!ok(r) && !isfinite(r->t.wall_s)) {
        printf(" FAILED: %s\n", r->msg);
        fflush(stdout);
        return;
    }
    num(r->s.c, 7, 4, 0);
    printf("  %-12s", r->t.binary.status == PIPE_BIN_NONE ? "-"
                      : pipeline_binary_status_name(r->t.binary.status));
    num(r->dsep_px, 7, 3, 1);
    num(r->dpa_deg, 7, 2, 1);
    num(r->ddm_mag, 7, 3, 1);
    printf(" %-4s |", bounds_label(r));
    num(r->method == PIPE_AUTO ? r->t.pred_error : NAN, 6, 3, 0);
    num(1.0 - r->s.c, 6, 3, 0);
    printf(" |");
    num(r->t.wall_s, 7, 3, 0);
    if (!ok(r))
        printf("  FAILED: %s", r->msg);
    printf("\n");
    fflush(stdout);
}

/* ---- summary ---- */

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* Median of the finite values of v (reordered); NAN when none. */
static double median_finite(double *v, int n)
{
    int m = 0;
    for (int i = 0; i < n; i++)
        if (isfinite(v[i]))
            v[m++] = v[i];
    if (m == 0)
        return NAN;
    qsort(v, (size_t)m, sizeof *v, cmp_double);
    return m % 2 ? v[m / 2] : 0.5 * (v[m / 2 - 1] + v[m / 2]);
}

static double frac(int k, int n) { return n > 0 ? (double)k / n : NAN; }

/* auto's misses: its c below BLIND_AUTO_LOW_C (or failed) on a condition
 * where some fixed method reached BLIND_FIXED_GOOD_C.  Names into buf. */
static int auto_misses(const blind_row *rows, int n, char *buf, size_t len)
{
    int count = 0;
    buf[0] = 0;
    for (int i = 0; i < n; i++) {
        const blind_row *a = &rows[i];
        if (a->method != PIPE_AUTO || (ok(a) && a->s.c >= BLIND_AUTO_LOW_C))
            continue;
        int good = 0;
        for (int j = 0; j < n && !good; j++)
            good = rows[j].method != PIPE_AUTO && ok(&rows[j]) &&
                   !strcmp(rows[j].cond, a->cond) &&
                   rows[j].s.c >= BLIND_FIXED_GOOD_C;
        if (good) {
            count++;
            size_t k = strlen(buf);
            snprintf(buf + k, len - k, " %s", a->cond);
        }
    }
    return count;
}

static void summary_auto(const blind_row *rows, int n)
{
    int runs = 0, met = 0;
    double target = 0.1;
    for (int i = 0; i < n; i++) {
        if (rows[i].method != PIPE_AUTO)
            continue;
        runs++;
        target = rows[i].target;
        met += ok(&rows[i]) && 1.0 - rows[i].s.c <= rows[i].target;
    }
    char names[1024];
    int miss = auto_misses(rows, n, names, sizeof names);
    printf("summary auto target: achieved 1-c <= %g in %d/%d (%.2f); c < "
           "%.2f while a fixed method reached >= %.2f: %d%s%s\n", target, met,
           runs, frac(met, runs), BLIND_AUTO_LOW_C, BLIND_FIXED_GOOD_C, miss,
           miss ? " --" : "", names);
}

/* "#   direct outside the bounds: photons-1e3 (unresolved) ..." */
static void print_outside(const blind_row *rows, int n, int method)
{
    int any = 0;
    for (int i = 0; i < n; i++) {
        const blind_row *r = &rows[i];
        if (r->method != method || !r->truth_binary || r->within)
            continue;
        if (!any)
            printf("#   %s outside the bounds:", pipeline_method_name(method));
        any = 1;
        if (!ok(r))
            printf(" %s (failed)", r->cond);
        else if (!isfinite(r->dsep_px))
            printf(" %s (%s)", r->cond, pipeline_binary_status_name(r->t.binary.status));
        else
            printf(" %s (%s %+.3f/%+.2f/%+.3f)", r->cond,
                   pipeline_binary_status_name(r->t.binary.status),
                   r->dsep_px, r->dpa_deg, r->ddm_mag);
    }
    if (any)
        printf("\n");
}

void blind_print_summary(const blind_row *rows, int n, const int *methods,
                         int nmethods)
{
    double *err = malloc(sizeof(double) * (size_t)(n + 1));
    if (!err)
        return;
    printf("\n# summary, per method: binary verdict within |dsep| <= %.2f "
           "px, |dPA| <= %.1f deg, |ddm| <= %.2f mag over the conditions "
           "with a binary (PA modulo 180 when ambiguous), and of those "
           "measured with the PA right (not flipped, not ambiguous); median "
           "1 - c over the runs that succeeded\n", BLIND_SEP_TOL_PX,
           BLIND_PA_TOL_DEG, BLIND_DM_TOL_MAG);
    for (int k = 0; k < nmethods; k++) {
        int nbin = 0, in = 0, oriented = 0, nrun = 0, nok = 0;
        for (int i = 0; i < n; i++) {
            const blind_row *r = &rows[i];
            if (r->method != methods[k])
                continue;
            err[nrun++] = ok(r) ? 1.0 - r->s.c : NAN;
            nok += ok(r);
            nbin += r->truth_binary;
            in += r->truth_binary && r->within;
            oriented += r->truth_binary && r->oriented;
        }
        double med = median_finite(err, nrun);
        printf("summary %s: binary within %d/%d (%.2f), PA right not flipped "
               "%d/%d (%.2f), median 1-c %.4f, %d/%d runs ok\n",
               pipeline_method_name(methods[k]), in, nbin, frac(in, nbin),
               oriented, nbin, frac(oriented, nbin), med, nok, nrun);
    }
    for (int k = 0; k < nmethods; k++)
        if (methods[k] == PIPE_AUTO)
            summary_auto(rows, n);
    for (int k = 0; k < nmethods; k++)
        print_outside(rows, n, methods[k]);
    free(err);
}

/* ---- CSV ---- */

static void csv_num(FILE *f, double v)
{
    if (isfinite(v))
        fprintf(f, ",%.6g", v);
    else
        fputc(',', f);
}

/* s with ',' and line breaks replaced, so that lines split on commas. */
static void csv_str(FILE *f, const char *s)
{
    fputc(',', f);
    for (; s && *s; s++)
        fputc(*s == ',' ? ';' : *s == '\n' || *s == '\r' ? ' ' : *s, f);
}

static const char *const columns =
    "condition,scene,mask,aperture_m,obstruction,phase_model,wavelength_nm,"
    "plate_scale_arcsec,sampling_nyq,r0_m,frames,frame_interval_s,width,"
    "height,photons,read_noise_e,gain_e_per_adu,bias_adu,adc_bits,peak_adu,"
    "hot_pixels,dead_pixels,offset_x_px,offset_y_px,jitter_px,true_sep_px,"
    "true_pa_deg,true_dm_mag,method,method_run,chosen,status,message,c,c_hp,"
    "one_minus_c,bin_status,bin_source,bin_sep_px,bin_sep_err_px,bin_pa_deg,"
    "bin_pa_err_deg,bin_dm_mag,bin_dm_err_mag,bin_why,dsep_px,dpa_deg,"
    "ddm_mag,within,oriented,img_dsep_px,img_dpa_deg,img_ddm_mag,"
    "target_error,pred_error,met_target,wall_s,cpu_s,wall_first_s,"
    "peak_rss_mb,crop_px,rejected\n";

/* The data set's columns, condition .. true_dm_mag. */
static void csv_data(FILE *f, const blind_row *r)
{
    const bench_sim *d = &r->sim;
    fprintf(f, "%s", r->cond);
    csv_str(f, d->scene);
    csv_str(f, d->mask ? d->mask : "nrm17");
    csv_num(f, d->aperture_m > 0 ? d->aperture_m : NAN);
    csv_num(f, d->obstruction);
    csv_str(f, d->phase_model == SIM_PHASE_PISTON ? "piston" : "screen");
    csv_num(f, (d->wavelength_m > 0 ? d->wavelength_m : 500e-9) * 1e9);
    csv_num(f, r->plate_scale_arcsec);
    csv_num(f, r->sampling_nyq);
    csv_num(f, d->r0_m);
    csv_num(f, d->nframes);
    csv_num(f, d->frame_interval_s > 0 ? d->frame_interval_s : 0.01);
    csv_num(f, d->width);
    csv_num(f, d->height);
    const double v[] = {d->photons, d->read_noise_e, d->gain_e_per_adu,
                        d->bias_adu, d->adc_bits, r->peak_adu, d->hot_pixels,
                        d->dead_pixels, d->offset_x_px, d->offset_y_px,
                        d->jitter_px, r->true_sep_px, r->true_pa_deg,
                        r->true_dm_mag};
    for (size_t i = 0; i < sizeof v / sizeof v[0]; i++)
        csv_num(f, v[i]);
}

/* The measurement's columns, method .. rejected. */
static void csv_result(FILE *f, const blind_row *r)
{
    const bench_verdict *b = &r->t.binary;
    csv_str(f, pipeline_method_name(r->method));
    csv_str(f, r->t.method_run >= 0 ? pipeline_method_name(r->t.method_run) : "");
    csv_str(f, r->t.chosen);
    csv_str(f, ok(r) ? "ok" : "failed");
    csv_str(f, r->msg);
    csv_num(f, r->s.c);
    csv_num(f, r->s.c_hp);
    csv_num(f, 1.0 - r->s.c);
    csv_str(f, pipeline_binary_status_name(b->status));
    csv_str(f, pipeline_binary_source_name(b->source));
    const double v[] = {b->sep_px, b->sep_err_px, b->pa_deg, b->pa_err_deg,
                        b->dm_mag, b->dm_err_mag};
    for (size_t i = 0; i < sizeof v / sizeof v[0]; i++)
        csv_num(f, v[i]);
    csv_str(f, b->why);
    const int auto_row = r->method == PIPE_AUTO;
    const double w[] = {r->dsep_px, r->dpa_deg, r->ddm_mag, r->within,
                        r->oriented, r->s.sep_err_px, r->s.pa_err_deg,
                        r->s.dm_err_mag, auto_row ? r->target : NAN,
                        r->t.pred_error,
                        auto_row ? (ok(r) && 1.0 - r->s.c <= r->target) : NAN,
                        r->t.wall_s, r->t.cpu_s, r->t.wall_first_s,
                        r->t.peak_rss_mb, r->t.crop_px, r->t.rejected};
    for (size_t i = 0; i < sizeof w / sizeof w[0]; i++)
        csv_num(f, w[i]);
}

int blind_write_csv(const char *path, const blind_row *rows, int n)
{
    FILE *f = fopen(path, "w");
    if (!f) {
        perror(path);
        return 1;
    }
    fputs(columns, f);
    for (int i = 0; i < n; i++) {
        csv_data(f, &rows[i]);
        csv_result(f, &rows[i]);
        fputc('\n', f);
    }
    if (fclose(f) != 0) {
        perror(path);
        return 1;
    }
    return 0;
}
