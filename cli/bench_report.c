/* bench_report.c - what `specklab bench` prints and writes: the streamed
 * table, Pareto fronts, scaling slopes, the paper's Table 2, CSV, chart
 * and catalogue rows (see bench_cli.h). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "bench_cli.h"
#include "catalog.h"
#include "chart.h"
#include "pipeline/pipeline.h"
#include "tsm/tsm.h"

static int ok(const bcli_row *r) { return r->status == SL_OK; }
static double err1(const bcli_row *r) { return 1.0 - r->s.c; }
static int is_binary(const bcli_row *r) { return !strcmp(r->scene, "binary"); }

/* " [crop,support]" for rows with skips other than the method's default. */
static void skips_suffix(const bcli_row *r, char *buf, size_t n)
{
    buf[0] = 0;
    if (r->skips < 0 || (r->method == PIPE_AUTO && r->skips == PIPE_SKIP_ALL))
        return;
    char k[48];
    if (r->method == PIPE_AUTO) { /* auto has all: name what is left out */
        pipeline_skips_name(PIPE_SKIP_ALL & ~r->skips, k, sizeof k);
        snprintf(buf, n, " [-%s]", k);
        for (char *c = buf; *c; c++)
            if (*c == ',')
                *c = '-';
        return;
    }
    pipeline_skips_name(r->skips, k, sizeof k);
    snprintf(buf, n, " [%s]", r->skips == 0 ? "none" : k);
}

void bcli_config_label(const bcli_row *r, char *buf, size_t n)
{
    const char *m = pipeline_method_name(r->method);
    char ref[64];
    skips_suffix(r, ref, sizeof ref);
    if (r->ref)
        snprintf(ref + strlen(ref), sizeof ref - strlen(ref), " +ref");
    if (r->method == PIPE_AUTO) {
        /* auto(E) and what ran: "auto .1: direct/64" */
        char ran[40] = "?";
        int mr = r->t.method_run;
        if (mr == PIPE_DIRECT)
            snprintf(ran, sizeof ran, "direct");
        else if (mr == PIPE_TSM || mr == PIPE_TSM_FOURIER)
            snprintf(ran, sizeof ran, "%s %.0f%s", mr == PIPE_TSM ? "tsm" : "tsmf",
                     r->t.nangles, strstr(r->t.chosen, " iter") ? "i" : "");
        if (isfinite(r->t.crop_px))
            snprintf(ran + strlen(ran), sizeof ran - strlen(ran), "/%.0f", r->t.crop_px);
        snprintf(buf, n, "auto %g%s: %s", r->target > 0 ? r->target : 0.1, ref, ran);
    } else if (r->method == PIPE_DIRECT) {
        if (isfinite(r->t.r2_px))
            snprintf(buf, n, "%s R2=%.0f%s", m, r->t.r2_px, ref);
        else if (r->r2 > 0)
            snprintf(buf, n, "%s R2=%d%s", m, r->r2, ref);
        else
            snprintf(buf, n, "%s R2=auto%s", m, ref);
    } else if (r->method == PIPE_TSM || r->method == PIPE_TSM_FOURIER) {
        const char *inv = r->inverse == TSM_INV_ITER ? " iter" : "";
        if (isfinite(r->t.nangles))
            snprintf(buf, n, "%s %.0f%s%s", m, r->t.nangles, inv, ref);
        else
            snprintf(buf, n, "%s %d%s%s", m, r->nangles > 0 ? r->nangles : 180, inv, ref);
    } else {
        snprintf(buf, n, "%s%s", m, ref);
    }
}

static void scene_label(const bcli_row *r, char *buf, size_t n)
{
    if (is_binary(r))
        snprintf(buf, n, "binary %g/%g", r->sep_lod, r->dm_mag);
    else
        snprintf(buf, n, "%s", r->scene);
    if (r->inject)
        snprintf(buf + strlen(buf), n - strlen(buf), " bad");
    if (r->oversample > 1)
        snprintf(buf + strlen(buf), n - strlen(buf), " os%g", r->oversample);
}

void bcli_print_header(void)
{
    printf("%-14s %-9s %5s %7s %-30s | %7s %7s %7s %6s | %7s %7s | %7s %7s %7s\n",
           "scene", "size", "frm", "photons", "config", "wall_s", "cpu_s",
           "first_s", "rss_MB", "1-c", "1-c_hp", "dsep_px", "dPA_deg",
           "ddm_mag");
    printf("%-14s %-9s %5s %7s %-30s |\n", "(binary sep", "", "", "",
           "lambda/D / dm)");
}

static void num(double v, int width, int prec, const char *sign)
{
    if (isfinite(v))
        printf(sign[0] == '+' ? " %+*.*f" : " %*.*f", width, prec, v);
    else
        printf(" %*s", width, "-");
}

void bcli_print_row(const bcli_row *r)
{
    char sc[48], cfg[64], size[24];
    scene_label(r, sc, sizeof sc);
    bcli_config_label(r, cfg, sizeof cfg);
    snprintf(size, sizeof size, "%dx%d", r->width, r->height);
    printf("%-14s %-9s %5d %7g %-30s |", sc, size, r->frames, r->photons, cfg);
    if (!ok(r) && !isfinite(r->t.wall_s)) {
        printf(" FAILED: %s\n", r->msg);
        fflush(stdout);
        return;
    }
    num(r->t.wall_s, 7, 3, "");
    num(r->t.cpu_s, 7, 3, "");
    num(r->t.wall_first_s, 7, 3, "");
    num(r->t.peak_rss_mb, 6, 0, "");
    printf(" |");
    num(err1(r), 7, 4, "");
    num(1.0 - r->s.c_hp, 7, 4, "");
    printf(" |");
    num(r->s.sep_err_px, 7, 3, "+");
    num(r->s.pa_err_deg, 7, 2, "+");
    num(r->s.dm_err_mag, 7, 3, "+");
    if (!ok(r))
        printf("  FAILED: %s", r->msg);
    else if (is_binary(r) && !r->s.binary_found)
        printf("  (companion not found)");
    printf("\n");
    fflush(stdout);
}

/* ---- Pareto fronts ---- */

static int same_data(const bcli_row *a, const bcli_row *b)
{
    return !strcmp(a->scene, b->scene) && a->width == b->width &&
           a->height == b->height && a->frames == b->frames &&
           a->photons == b->photons && a->sep_lod == b->sep_lod &&
           a->dm_mag == b->dm_mag && a->pa_deg == b->pa_deg &&
           a->inject == b->inject && a->oversample == b->oversample;
}

void bcli_mark_fronts(GArray *rows)
{
    int ngroup = 0;
    bcli_row *r = (bcli_row *)(void *)rows->data;
    int n = (int)rows->len;
    for (int i = 0; i < n; i++) {
        r[i].group = -1;
        for (int j = 0; j < i && r[i].group < 0; j++)
            if (same_data(&r[i], &r[j]))
                r[i].group = r[j].group;
        if (r[i].group < 0)
            r[i].group = ngroup++;
    }
    double *x = malloc(sizeof(double) * (size_t)(n + 1));
    double *y = malloc(sizeof(double) * (size_t)(n + 1));
    int *idx = malloc(sizeof(int) * (size_t)(n + 1));
    unsigned char *f = malloc((size_t)n + 1);
    for (int g = 0; x && y && idx && f && g < ngroup; g++) {
        int m = 0;
        for (int i = 0; i < n; i++)
            if (r[i].group == g) {
                idx[m] = i;
                x[m] = ok(&r[i]) ? r[i].t.wall_s : NAN;
                y[m++] = ok(&r[i]) ? err1(&r[i]) : NAN;
            }
        bench_pareto(x, y, m, f);
        for (int k = 0; k < m; k++)
            r[idx[k]].front = f[k];
    }
    free(x);
    free(y);
    free(idx);
    free(f);
}

static int by_wall(const void *a, const void *b)
{
    const bcli_row *p = *(const bcli_row *const *)a;
    const bcli_row *q = *(const bcli_row *const *)b;
    return (p->t.wall_s > q->t.wall_s) - (p->t.wall_s < q->t.wall_s);
}

void bcli_print_fronts(GArray *rows)
{
    bcli_row *r = (bcli_row *)(void *)rows->data;
    int n = (int)rows->len, shown = -1;
    const bcli_row **f = malloc(sizeof *f * (size_t)(n + 1));
    if (!f)
        return;
    printf("\n# Pareto front of (wall time, 1 - c) per data set, fastest first\n");
    for (int i = 0; i < n; i++) {
        if (r[i].group <= shown)
            continue;
        shown = r[i].group;
        int m = 0;
        for (int j = 0; j < n; j++)
            if (r[j].group == shown && r[j].front)
                f[m++] = &r[j];
        if (m == 0)
            continue;
        qsort(f, (size_t)m, sizeof *f, by_wall);
        char sc[48];
        scene_label(&r[i], sc, sizeof sc);
        printf("%s %dx%d, %d frames, %g photons:\n", sc, r[i].width,
               r[i].height, r[i].frames, r[i].photons);
        for (int k = 0; k < m; k++) {
            char cfg[64];
            bcli_config_label(f[k], cfg, sizeof cfg);
            printf("  %-30s %8.3f s  1-c %.4f\n", cfg, f[k]->t.wall_s, err1(f[k]));
        }
    }
    free(f);
}

/* ---- scaling ---- */

enum { VAR_FRAMES, VAR_PIXELS, VAR_ANGLES };

static double var_value(const bcli_row *r, int var)
{
    return var == VAR_FRAMES ? r->frames
         : var == VAR_PIXELS ? (double)r->width * r->height
         : r->nangles > 0 ? r->nangles : 180;
}

/* Everything but the varied quantity agrees. */
static int same_but(const bcli_row *a, const bcli_row *b, int var)
{
    return !strcmp(a->scene, b->scene) && a->photons == b->photons &&
           a->sep_lod == b->sep_lod && a->dm_mag == b->dm_mag &&
           a->method == b->method && a->r2 == b->r2 && a->ref == b->ref &&
           a->skips == b->skips && a->target == b->target &&
           a->inject == b->inject && a->oversample == b->oversample &&
           (var == VAR_FRAMES || a->frames == b->frames) &&
           (var == VAR_PIXELS || (a->width == b->width && a->height == b->height)) &&
           (var == VAR_ANGLES || a->nangles == b->nangles);
}

static const char *model(int var, int method)
{
    if (var == VAR_FRAMES)
        return "model: setup + frames x per-frame cost -> slope 1 once frames dominate";
    if (var == VAR_ANGLES)
        return "model: FFT (fixed) + angles x (slice or Radon + 1-D bispectrum) -> slope <= 1";
    return method == PIPE_DIRECT
        ? "model: triples ~ r_c^2 R2^2, R2 = 0.14 N -> N^4 = pixels^2"
        : "model: N^2 log N FFT + angles x N^2 (Radon) or x N^2/4 (bispectrum) -> ~pixels^1";
}

void bcli_print_scaling(GArray *rows)
{
    static const char *names[] = {"frames", "pixels", "projections"};
    bcli_row *r = (bcli_row *)(void *)rows->data;
    int n = (int)rows->len, header = 0;
    unsigned char *used = calloc((size_t)n + 1, 1);
    for (int var = 0; used && var < 3; var++) {
        memset(used, 0, (size_t)n + 1);
        for (int i = 0; i < n; i++) {
            if (used[i] || !ok(&r[i]) ||
                (var == VAR_ANGLES && r[i].method == PIPE_DIRECT))
                continue;
            double sx = 0, sy = 0, sxx = 0, sxy = 0, lo = INFINITY, hi = 0;
            int m = 0;
            for (int j = i; j < n; j++)
                if (!used[j] && ok(&r[j]) && same_but(&r[i], &r[j], var)) {
                    used[j] = 1;
                    double lx = log(var_value(&r[j], var)), ly = log(r[j].t.wall_s);
                    sx += lx; sy += ly; sxx += lx * lx; sxy += lx * ly; m++;
                    lo = fmin(lo, var_value(&r[j], var));
                    hi = fmax(hi, var_value(&r[j], var));
                }
            double den = m * sxx - sx * sx;
            if (m < 3 || !(den > 0) || !(hi > lo))
                continue;
            if (!header++)
                printf("\n# Scaling: least-squares slope of log(wall time) "
                       "against log(x), other parameters fixed\n");
            char cfg[64], sc[48], geo[64];
            bcli_row lab = r[i]; /* label without the varied quantity */
            lab.t.r2_px = lab.t.nangles = NAN;
            bcli_config_label(&lab, cfg, sizeof cfg);
            if (var == VAR_ANGLES)
                snprintf(cfg, sizeof cfg, "%s%s", pipeline_method_name(lab.method),
                         lab.ref ? " +ref" : "");
            scene_label(&r[i], sc, sizeof sc);
            if (var == VAR_PIXELS)
                snprintf(geo, sizeof geo, "%d frames, %g ph", r[i].frames, r[i].photons);
            else if (var == VAR_FRAMES)
                snprintf(geo, sizeof geo, "%dx%d, %g ph", r[i].width, r[i].height,
                         r[i].photons);
            else
                snprintf(geo, sizeof geo, "%dx%d, %d frames, %g ph", r[i].width,
                         r[i].height, r[i].frames, r[i].photons);
            printf("time ~ %s^%.2f over %g..%g (%d points): %s; %s, %s\n  %s\n",
                   names[var], (m * sxy - sx * sy) / den, lo, hi, m, cfg, sc,
                   geo, model(var, r[i].method));
        }
    }
    free(used);
}

/* ---- files ---- */

static void csv_num(FILE *f, double v)
{
    if (isfinite(v))
        fprintf(f, ",%.6g", v);
    else
        fputc(',', f);
}

int bcli_write_csv(const char *path, GArray *rows, double base_rss_mb)
{
    FILE *f = fopen(path, "w");
    if (!f) {
        perror(path);
        return 1;
    }
    fprintf(f, "scene,sep_lod,pa_deg,dm_mag,width,height,frames,photons,method,"
            "nangles,r2,ref,repeat,threads,wall_s,cpu_s,first_wall_s,"
            "first_cpu_s,peak_rss_mb,base_rss_mb,ntriples,c,c_hp,err_1mc,"
            "err_hp,sep_px,pa_deg_meas,dm_mag_meas,sep_err_px,pa_err_deg,"
            "dm_err_mag,floor_sep_err_px,floor_pa_err_deg,floor_dm_err_mag,"
            "group,pareto,status,skips,target_error,bad_frames,oversample,"
            "method_run,crop_px,cutoff_cyc_px,rejected,pred_error,chosen,"
            "inverse\n");
    for (guint i = 0; i < rows->len; i++) {
        const bcli_row *r = &g_array_index(rows, bcli_row, i);
        int bin = is_binary(r);
        fprintf(f, "%s", r->scene);
        csv_num(f, bin ? r->sep_lod : NAN);
        csv_num(f, bin ? r->pa_deg : NAN);
        csv_num(f, bin ? r->dm_mag : NAN);
        fprintf(f, ",%d,%d,%d,%g,%s", r->width, r->height, r->frames,
                r->photons, pipeline_method_name(r->method));
        csv_num(f, r->method == PIPE_DIRECT ? NAN : r->t.nangles);
        csv_num(f, r->method == PIPE_DIRECT ? r->t.r2_px : NAN);
        fprintf(f, ",%d,%d,%d", r->ref, r->repeat, r->threads);
        double v[] = {r->t.wall_s, r->t.cpu_s, r->t.wall_first_s,
                      r->t.cpu_first_s, r->t.peak_rss_mb, base_rss_mb,
                      r->t.ntriples, r->s.c, r->s.c_hp, 1 - r->s.c,
                      1 - r->s.c_hp, r->s.sep_px, r->s.pa_deg, r->s.dm_mag,
                      r->s.sep_err_px, r->s.pa_err_deg, r->s.dm_err_mag,
                      r->floor.sep_err_px, r->floor.pa_err_deg,
                      r->floor.dm_err_mag};
        for (size_t k = 0; k < sizeof v / sizeof v[0]; k++)
            csv_num(f, v[k]);
        /* The message is quoted CSV: double any quote. */
        fprintf(f, ",%d,%d,\"", r->group, r->front);
        for (const char *p = ok(r) ? "ok" : r->msg; *p; p++)
            fprintf(f, *p == '"' ? "\"\"" : "%c", *p);
        char sk[48];
        pipeline_skips_name(r->skips < 0 ? 0 : r->skips, sk, sizeof sk);
        fprintf(f, "\",%s", r->skips < 0 ? "default" : sk);
        csv_num(f, r->method == PIPE_AUTO ? (r->target > 0 ? r->target : 0.1) : NAN);
        fprintf(f, ",%d", r->inject);
        csv_num(f, r->oversample > 1 ? r->oversample : 1);
        fprintf(f, ",%s", r->t.method_run >= 0 ? pipeline_method_name(r->t.method_run) : "");
        csv_num(f, r->t.crop_px);
        csv_num(f, r->t.cutoff_cyc_px);
        csv_num(f, r->t.rejected);
        csv_num(f, r->t.pred_error);
        fprintf(f, ",\"%s\",%s\n", r->t.chosen,
                r->method == PIPE_DIRECT ? "" : r->inverse == TSM_INV_ITER ? "iter" : "fbp");
    }
    int bad = ferror(f) | (fclose(f) != 0);
    if (bad)
        fprintf(stderr, "specklab bench: writing %s failed\n", path);
    else
        fprintf(stderr, "bench: CSV of %u rows\n", rows->len);
    return bad;
}

/* A configuration as asked, the same on every data set ("tsm 18",
 * "direct R2=16", "auto 0.1 [-crop]"), without the reference. */
static void series_key(const bcli_row *r, char *buf, size_t n)
{
    char sk[64], par[32] = "";
    skips_suffix(r, sk, sizeof sk);
    if (r->method == PIPE_DIRECT && r->r2 > 0)
        snprintf(par, sizeof par, " R2=%d", r->r2);
    else if (r->method == PIPE_DIRECT)
        snprintf(par, sizeof par, " R2=auto");
    else if (r->method == PIPE_AUTO)
        snprintf(par, sizeof par, " %g", r->target > 0 ? r->target : 0.1);
    else /* pipeline.h: 0 projections means 180 */
        snprintf(par, sizeof par, " %d%s", r->nangles > 0 ? r->nangles : 180,
                 r->inverse == TSM_INV_ITER ? " iter" : "");
    snprintf(buf, n, "%s%s%.40s", pipeline_method_name(r->method), par, sk);
}

typedef struct chart_set {
    char key[CHART_MAX_SERIES][72], name[CHART_MAX_SERIES][80];
    int method[CHART_MAX_SERIES];
    chart_series s[CHART_MAX_SERIES];
    int n;
} chart_set;

/* The row's series, added when new: colour by method, shape by the
 * configuration within the method, filled with a reference; -1 when full. */
static int series_of(chart_set *cs, const bcli_row *r)
{
    char key[72], name[80];
    series_key(r, key, sizeof key);
    snprintf(name, sizeof name, "%s%s", key, r->ref ? " +ref" : "");
    int variant = -1, keys = 0; /* the twin's shape, else the next one */
    for (int i = 0; i < cs->n; i++) {
        if (!strcmp(cs->name[i], name))
            return i;
        if (cs->method[i] != r->method)
            continue;
        if (!strcmp(cs->key[i], key))
            variant = cs->s[i].shape;
        int first = 1;
        for (int j = 0; j < i; j++)
            first &= cs->method[j] != r->method || strcmp(cs->key[j], cs->key[i]) != 0;
        keys += first;
    }
    variant = variant >= 0 ? variant : keys;
    if (cs->n == CHART_MAX_SERIES)
        return -1;
    int i = cs->n++;
    snprintf(cs->key[i], sizeof cs->key[i], "%s", key);
    snprintf(cs->name[i], sizeof cs->name[i], "%s", name);
    cs->method[i] = r->method;
    /* past the shapes, the next palette colours keep the series apart */
    cs->s[i] = (chart_series){cs->name[i], r->method + 4 * (variant / CHART_NSHAPES),
                              variant, r->ref};
    return i;
}

/* Panels: data sets with >= 3 measured points, in order, at most 12. */
static int chart_panels(GArray *rows, char titles[][112], int *gid)
{
    int np = 0, n = (int)rows->len;
    for (int i = 0; i < n && np < CHART_MAX_PANELS; i++) {
        const bcli_row *r = &g_array_index(rows, bcli_row, i);
        int seen = 0, cnt = 0;
        for (int k = 0; k < np; k++)
            seen |= gid[k] == r->group;
        for (int j = 0; j < n && !seen; j++)
            cnt += g_array_index(rows, bcli_row, j).group == r->group &&
                   ok(&g_array_index(rows, bcli_row, j));
        if (seen || cnt < 3)
            continue;
        char sc[48];
        scene_label(r, sc, sizeof sc);
        snprintf(titles[np], 112, "%s %dx%d, %d frames, %g photons", sc, r->width,
                 r->height, r->frames, r->photons);
        gid[np++] = r->group;
    }
    return np;
}

int bcli_write_png(const char *path, GArray *rows)
{
    char titles[CHART_MAX_PANELS][112];
    const char *tp[CHART_MAX_PANELS];
    int gid[CHART_MAX_PANELS], n = (int)rows->len, m = 0;
    int np = chart_panels(rows, titles, gid);
    chart_set *cs = calloc(1, sizeof *cs);
    chart_point *pts = malloc(sizeof *pts * (size_t)(n + 1));
    if (!cs || !pts) {
        free(cs);
        free(pts);
        return 1;
    }
    for (int i = 0; i < n; i++) {
        const bcli_row *r = &g_array_index(rows, bcli_row, i);
        for (int k = 0; k < np && ok(r); k++) {
            int s = gid[k] == r->group ? series_of(cs, r) : -1;
            if (s >= 0)
                pts[m++] = (chart_point){r->t.wall_s, err1(r), s, k, r->front};
        }
    }
    for (int k = 0; k < np; k++)
        tp[k] = titles[k];
    chart_data d = {pts, m, cs->s, cs->n, tp, np, "run time (s)", "error 1 \u2212 c",
                    "Pareto front"};
    int rc = 0;
    sl_err e = {0};
    if (np == 0)
        fprintf(stderr, "bench: no data set has 3 measured points: no chart\n");
    else if (chart_write_png(path, &d, &e) != SL_OK)
        rc = fprintf(stderr, "specklab bench: %s\n", e.msg) > 0;
    else
        fprintf(stderr, "bench: chart of %d panels, %d series\n", np, cs->n);
    free(pts);
    free(cs);
    return rc;
}

static char *params_json(const bcli_row *r, double base_rss_mb)
{
    JsonBuilder *b = json_builder_new();
    json_builder_begin_object(b);
#define NUM(k, v) do { json_builder_set_member_name(b, k); \
        if (isfinite(v)) json_builder_add_double_value(b, v); \
        else json_builder_add_null_value(b); } while (0)
    NUM("nangles", r->method == PIPE_DIRECT ? NAN : r->t.nangles);
    NUM("r2_px", r->method == PIPE_DIRECT ? r->t.r2_px : NAN);
    json_builder_set_member_name(b, "reference");
    json_builder_add_boolean_value(b, r->ref);
    json_builder_set_member_name(b, "repeat");
    json_builder_add_int_value(b, r->repeat);
    json_builder_set_member_name(b, "threads");
    json_builder_add_int_value(b, r->threads);
    NUM("c", r->s.c);
    NUM("c_hp", r->s.c_hp);
    NUM("first_wall_s", r->t.wall_first_s);
    NUM("base_rss_mb", base_rss_mb);
    NUM("ntriples", r->t.ntriples);
    if (is_binary(r)) {
        NUM("sep_lod", r->sep_lod);
        NUM("pa_deg", r->pa_deg);
        NUM("dm_mag", r->dm_mag);
    }
#undef NUM
    json_builder_end_object(b);
    JsonGenerator *g = json_generator_new();
    JsonNode *root = json_builder_get_root(b);
    json_generator_set_root(g, root);
    char *text = json_generator_to_data(g, NULL);
    json_node_unref(root);
    g_object_unref(g);
    g_object_unref(b);
    return text;
}

int bcli_write_catalog(const char *path, GArray *rows, double base_rss_mb)
{
    catalog *cat = NULL;
    sl_err e = {0};
    if (catalog_open(&cat, path, &e) != SL_OK) {
        fprintf(stderr, "specklab bench: %s\n", e.msg);
        return 1;
    }
    char *rev = NULL, *junk = NULL; /* git's complaint outside a work tree */
    int st = 0;
    if (!g_spawn_command_line_sync("git rev-parse --short HEAD", &rev, &junk,
                                   &st, NULL) || st != 0) {
        g_free(rev);
        rev = NULL;
    }
    g_free(junk);
    if (rev)
        g_strstrip(rev);
    int rc = SL_OK, added = 0;
    for (guint i = 0; i < rows->len && rc == SL_OK; i++) {
        const bcli_row *r = &g_array_index(rows, bcli_row, i);
        if (!ok(r))
            continue;
        catalog_bench b;
        catalog_bench_init(&b);
        char *pj = params_json(r, base_rss_mb);
        b.host = g_get_host_name();
        b.git_rev = rev ? rev : "";
        b.method = pipeline_method_name(r->method);
        b.params_json = pj;
        b.frames = r->frames;
        b.width = r->width;
        b.height = r->height;
        b.photons = r->photons > 0 ? r->photons : NAN;
        b.scene = r->scene;
        b.wall_s = r->t.wall_s;
        b.cpu_s = r->t.cpu_s;
        b.peak_rss_mb = r->t.peak_rss_mb;
        b.err_1mc = 1 - r->s.c;
        b.err_hp = 1 - r->s.c_hp;
        b.sep_err_px = r->s.sep_err_px;
        b.pa_err_deg = r->s.pa_err_deg;
        b.dm_err_mag = r->s.dm_err_mag;
        if ((rc = catalog_bench_insert(cat, &b, NULL)) != SL_OK)
            fprintf(stderr, "specklab bench: %s: %s\n", path, catalog_errmsg(cat));
        added += rc == SL_OK;
        g_free(pj);
    }
    if (rc == SL_OK)
        fprintf(stderr, "bench: added %d rows to %s\n", added, path);
    g_free(rev);
    catalog_close(cat);
    return rc != SL_OK;
}
