/* mask.c - see mask.h: building, reading, writing and rendering masks;
 * the layout search (mask_generate) is mask_gen.c. */
#include "mask.h"
#include "mask_int.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

struct mask {
    int nholes;            /* 0 for a filled aperture */
    double hole_d_m;       /* 0 for a filled aperture */
    double diameter_m;     /* filled aperture; 0 for holes */
    double obstruction;    /* filled: central obstruction / diameter */
    double extent_m, max_baseline_m, min_spacing_m;
    long redundancy;       /* -1 for a filled aperture */
    char name[16];
    double *x_m, *y_m;     /* point into xy */
    double xy[];           /* 2 * nholes */
};

/* ---- redundancy ------------------------------------------------------- */

/* Redundant pairs among nb baselines: O(nb^2), 9180 tests for 17 holes. */
static long count_pairs(const double *bx, const double *by, int nb,
                        double d2)
{
    long c = 0;
    for (int k = 0; k < nb; k++)
        for (int l = k + 1; l < nb; l++)
            c += pair_q(bx[k], by[k], bx[l], by[l]) < d2;
    return c;
}

/* ---- construction ----------------------------------------------------- */

static mask *mask_alloc(int nholes)
{
    mask *m = calloc(1, sizeof *m + 2 * (size_t)nholes * sizeof(double));
    if (!m)
        return NULL;
    m->nholes = nholes;
    m->x_m = m->xy;
    m->y_m = m->xy + nholes;
    strcpy(m->name, "custom");
    return m;
}

/* Non-finite centres and overlapping holes.  With lines (file input) the
 * message names the file and both lines, otherwise the hole indices. */
static int check_holes(const double *x, const double *y, int n, double d,
                       const int *lines, const char *path, sl_err *err)
{
    for (int i = 0; i < n; i++)
        if (!isfinite(x[i]) || !isfinite(y[i]))
            return lines ? sl_seterr(err, SL_EDATA,
                                     "%s:%d: hole centre is not finite",
                                     path, lines[i])
                         : sl_seterr(err, SL_EDATA,
                                     "mask: hole %d centre is not finite",
                                     i);
    for (int i = 0; i < n; i++)
        for (int j = i + 1; j < n; j++) {
            double dx = x[j] - x[i], dy = y[j] - y[i];
            if (dx * dx + dy * dy >= d * d)
                continue;
            double dist = sqrt(dx * dx + dy * dy);
            if (lines)
                return sl_seterr(err, SL_EDATA,
                                 "%s:%d: hole (%g, %g) overlaps the hole at "
                                 "line %d: centre distance %g m < hole "
                                 "diameter %g m",
                                 path, lines[j], x[j], y[j], lines[i], dist,
                                 d);
            return sl_seterr(err, SL_EDATA,
                             "mask: holes %d and %d overlap: centre distance "
                             "%g m < hole diameter %g m",
                             i, j, dist, d);
        }
    return SL_OK;
}

/* Copy validated holes into a new mask and derive its figures. */
static mask *make_holes(const double *x, const double *y, int n, double d,
                        sl_err *err)
{
    size_t nb = (size_t)n * (size_t)(n - 1) / 2;
    double *b = malloc(2 * nb * sizeof *b);
    mask *m = mask_alloc(n);
    if (!m || !b) {
        sl_seterr(err, SL_ENOMEM, "mask: out of memory for %d holes", n);
        goto fail_alloc;
    }
    m->hole_d_m = d;
    memcpy(m->x_m, x, (size_t)n * sizeof *x);
    memcpy(m->y_m, y, (size_t)n * sizeof *y);
    baselines(x, y, n, b, b + nb);
    double qmax = 0, qmin = INFINITY;
    for (size_t k = 0; k < nb; k++) {
        double q = b[k] * b[k] + b[nb + k] * b[nb + k];
        qmax = q > qmax ? q : qmax;
        qmin = q < qmin ? q : qmin;
    }
    m->max_baseline_m = sqrt(qmax);
    m->min_spacing_m = sqrt(qmin);
    m->extent_m = m->max_baseline_m + d;
    m->redundancy = count_pairs(b, b + nb, (int)nb, d * d);
    free(b);
    return m;
fail_alloc:
    free(b);
    free(m);
    return NULL;
}

mask *mask_new_full(double diameter_m)
{
    if (!(isfinite(diameter_m) && diameter_m > 0))
        return NULL;
    mask *m = mask_alloc(0);
    if (!m)
        return NULL;
    m->diameter_m = diameter_m;
    m->extent_m = diameter_m;
    m->max_baseline_m = diameter_m;
    m->redundancy = -1;
    return m;
}

mask *mask_new_full_obstructed(double diameter_m, double obstruction,
                               sl_err *err)
{
    if (!(isfinite(diameter_m) && diameter_m > 0)) {
        sl_seterr(err, SL_EINVAL, "mask: aperture diameter %g m is not > 0",
                  diameter_m);
        return NULL;
    }
    if (!(obstruction >= 0 && obstruction <= MASK_MAX_OBSTRUCTION)) {
        sl_seterr(err, SL_EINVAL, "mask: central obstruction %g (a fraction "
                  "of the diameter) must lie in [0, %g]", obstruction,
                  MASK_MAX_OBSTRUCTION);
        return NULL;
    }
    mask *m = mask_new_full(diameter_m);
    if (!m) {
        sl_seterr(err, SL_ENOMEM, "mask: out of memory");
        return NULL;
    }
    m->obstruction = obstruction;
    return m;
}

mask *mask_new_holes(const double *x_m, const double *y_m, int nholes,
                     double hole_diameter_m, sl_err *err)
{
    if (!x_m || !y_m || nholes < 2 || nholes > MASK_MAX_HOLES) {
        sl_seterr(err, SL_EINVAL, "mask: %d holes (need 2..%d centres)",
                  nholes, MASK_MAX_HOLES);
        return NULL;
    }
    if (!(isfinite(hole_diameter_m) && hole_diameter_m > 0)) {
        sl_seterr(err, SL_EDATA, "mask: hole diameter %g m is not > 0",
                  hole_diameter_m);
        return NULL;
    }
    if (check_holes(x_m, y_m, nholes, hole_diameter_m, NULL, NULL, err))
        return NULL;
    return make_holes(x_m, y_m, nholes, hole_diameter_m, err);
}

void mask_free(mask *m)
{
    free(m);
}

/* ---- file I/O ---------------------------------------------------------- */

/* One number at *p followed by whitespace or the end; advances *p. */
static int parse_num(const char **p, double *v)
{
    char *end;
    *v = strtod(*p, &end);
    if (end == *p || (*end && *end != ' ' && *end != '\t'))
        return -1;
    *p = end;
    return 0;
}

static int only_space(const char *s)
{
    return s[strspn(s, " \t\r\n\v\f")] == '\0';
}

/* What mask_read has read so far: the diameter (NAN until its line) and
 * the holes with their line numbers (fixed capacity, 5 KB). */
typedef struct mask_text {
    const char *path;
    double d;
    double x[MASK_MAX_HOLES], y[MASK_MAX_HOLES];
    int lines[MASK_MAX_HOLES], n;
} mask_text;

static const char mask_key[] = "hole_diameter_m";

/* The "hole_diameter_m <metres>" line, p after the key. */
static int read_diameter(mask_text *t, const char *p, int lineno, sl_err *err)
{
    if (!isnan(t->d))
        return sl_seterr(err, SL_EFORMAT, "%s:%d: second '%s' line", t->path,
                         lineno, mask_key);
    if (parse_num(&p, &t->d) || !only_space(p))
        return sl_seterr(err, SL_EFORMAT, "%s:%d: expected '%s <metres>'",
                         t->path, lineno, mask_key);
    if (!(isfinite(t->d) && t->d > 0))
        return sl_seterr(err, SL_EDATA, "%s:%d: hole diameter %g is not a "
                         "finite number > 0", t->path, lineno, t->d);
    return SL_OK;
}

/* An "x_m y_m" line (line: the whole text, for the message). */
static int read_hole(mask_text *t, const char *p, const char *line,
                     int lineno, sl_err *err)
{
    double v[2] = {0, 0};
    if (parse_num(&p, &v[0]) || parse_num(&p, &v[1]) || !only_space(p))
        return sl_seterr(err, SL_EFORMAT, "%s:%d: expected 'x_m y_m' (two "
                         "numbers) or '%s <metres>', got '%s'", t->path,
                         lineno, mask_key, line);
    if (!isfinite(v[0]) || !isfinite(v[1]))
        return sl_seterr(err, SL_EDATA, "%s:%d: hole centre is not a finite "
                         "number", t->path, lineno);
    if (isnan(t->d))
        return sl_seterr(err, SL_EFORMAT, "%s:%d: hole given before the "
                         "required '%s' line", t->path, lineno, mask_key);
    if (t->n == MASK_MAX_HOLES)
        return sl_seterr(err, SL_ERANGE, "%s:%d: more than %d holes", t->path,
                         lineno, MASK_MAX_HOLES);
    t->x[t->n] = v[0];
    t->y[t->n] = v[1];
    t->lines[t->n++] = lineno;
    return SL_OK;
}

/* Every line of f into t; the line count in *lineno. */
static int read_lines(mask_text *t, FILE *f, int *lineno, sl_err *err)
{
    const size_t klen = sizeof mask_key - 1;
    char *buf = NULL;
    size_t bufsz = 0;
    int rc = SL_OK;
    while (rc == SL_OK && getline(&buf, &bufsz, f) >= 0) {
        (*lineno)++;
        buf[strcspn(buf, "#\r\n")] = '\0'; /* comment, line end */
        if (only_space(buf))
            continue;
        const char *p = buf + strspn(buf, " \t");
        /* the key, then a blank or the line's end ('\0' is in the set) */
        if (strncmp(p, mask_key, klen) == 0 && strchr(" \t", p[klen]))
            rc = read_diameter(t, p + klen, *lineno, err);
        else
            rc = read_hole(t, p, buf, *lineno, err);
    }
    free(buf);
    return rc;
}

int mask_read(mask **out, const char *path, sl_err *err)
{
    int rc = SL_OK, lineno = 0;
    *out = NULL;
    mask_text *t = calloc(1, sizeof *t);
    FILE *f = fopen(path, "r");
    if (!f) {
        rc = sl_seterr(err, SL_EIO, "%s: cannot open: %s", path, strerror(errno));
        goto done;
    }
    if (!t) {
        rc = sl_seterr(err, SL_ENOMEM, "%s: out of memory", path);
        goto done;
    }
    t->path = path;
    t->d = NAN;
    if ((rc = read_lines(t, f, &lineno, err)) != SL_OK)
        goto done;
    if (ferror(f))
        rc = sl_seterr(err, SL_EIO, "%s:%d: read error", path, lineno);
    else if (isnan(t->d))
        rc = sl_seterr(err, SL_EFORMAT, "%s:%d: end of file without the "
                       "required '%s' line", path, lineno, mask_key);
    else if (t->n < 2)
        rc = sl_seterr(err, SL_EFORMAT, "%s:%d: end of file after %d hole%s; "
                       "a mask needs at least 2", path, lineno, t->n,
                       t->n == 1 ? "" : "s");
    else
        rc = check_holes(t->x, t->y, t->n, t->d, t->lines, path, err);
    if (rc == SL_OK && !(*out = make_holes(t->x, t->y, t->n, t->d, err)))
        rc = SL_ENOMEM;
done:
    if (f)
        fclose(f);
    free(t);
    return rc;
}

int mask_write(const mask *m, const char *path, sl_err *err)
{
    if (m->nholes == 0)
        return sl_seterr(err, SL_EINVAL,
                         "%s: a filled aperture has no mask-file form", path);
    FILE *f = fopen(path, "w");
    if (!f)
        return sl_seterr(err, SL_EIO, "%s: cannot create: %s", path,
                         strerror(errno));
    int bad = fprintf(f,
                      "# specklab aperture mask '%s': %d holes, redundancy "
                      "%ld\n# x_m y_m: centres in metres, +x east (right), "
                      "+y north\nhole_diameter_m %.17g\n",
                      m->name, m->nholes, m->redundancy, m->hole_d_m) < 0;
    for (int i = 0; i < m->nholes && !bad; i++)
        bad = fprintf(f, "%.17g %.17g\n", m->x_m[i], m->y_m[i]) < 0;
    int saved = errno;
    if (fclose(f) != 0 && !bad) {
        bad = 1;
        saved = errno;
    }
    if (bad)
        return sl_seterr(err, SL_EIO, "%s: write failed: %s", path,
                         strerror(saved));
    return SL_OK;
}

int mask_named(mask **out, const char *name, sl_err *err)
{
    *out = NULL;
    if (name && strcmp(name, "nrm17") == 0) {
        mask_gen_opts o;
        mask_gen_defaults(&o);
        int rc = mask_generate(out, &o, err);
        if (rc)
            return rc;
    } else if (name && strcmp(name, "full") == 0) {
        *out = mask_new_full(1.1);
        if (!*out)
            return sl_seterr(err, SL_ENOMEM, "mask: out of memory");
    } else
        return sl_seterr(err, SL_EINVAL,
                         "mask: unknown pupil '%s' (known: nrm17, full)",
                         name ? name : "(null)");
    strcpy((*out)->name, name);
    return SL_OK;
}

/* ---- accessors --------------------------------------------------------- */

int mask_nholes(const mask *m) { return m->nholes; }
double mask_hole_diameter_m(const mask *m) { return m->hole_d_m; }
int mask_is_full(const mask *m) { return m->nholes == 0; }
double mask_diameter_m(const mask *m) { return m->diameter_m; }
double mask_obstruction(const mask *m) { return m->obstruction; }
double mask_extent_m(const mask *m) { return m->extent_m; }
double mask_max_baseline_m(const mask *m) { return m->max_baseline_m; }
double mask_min_spacing_m(const mask *m) { return m->min_spacing_m; }
long mask_redundancy(const mask *m) { return m->redundancy; }
const char *mask_name(const mask *m) { return m->name; }

void mask_hole(const mask *m, int i, double *x_m, double *y_m)
{
    *x_m = m->x_m[i];
    *y_m = m->y_m[i];
}

/* ---- rendering --------------------------------------------------------- */

#define RENDER_SUB 8

/* Add the coverage of a disk of radius r (pixels) centred hx, hy pixels
 * from the grid centre.  Coordinates are taken relative to the centre as
 * (integer offset - h), so a mirrored layout renders bit-exactly mirrored.
 * Only edge pixels are supersampled: about 2*pi*r of them per disk. */
static void render_disk(float *pupil, int n, double hx, double hy,
                        double r, int subtract)
{
    int c = n / 2;
    double r2 = r * r;
    double off[RENDER_SUB];
    for (int s = 0; s < RENDER_SUB; s++)
        off[s] = (s + 0.5) / RENDER_SUB - 0.5; /* exact, antisymmetric */
    int x0 = (int)floor(hx - r) - 1 + c, x1 = (int)ceil(hx + r) + 1 + c;
    int y0 = (int)floor(hy - r) - 1 + c, y1 = (int)ceil(hy + r) + 1 + c;
    x0 = x0 < 0 ? 0 : x0;
    y0 = y0 < 0 ? 0 : y0;
    x1 = x1 > n - 1 ? n - 1 : x1;
    y1 = y1 > n - 1 ? n - 1 : y1;
    for (int iy = y0; iy <= y1; iy++) {
        double v = (double)(iy - c) - hy, av = fabs(v);
        double vn = av > 0.5 ? av - 0.5 : 0, vf = av + 0.5;
        for (int ix = x0; ix <= x1; ix++) {
            double u = (double)(ix - c) - hx, au = fabs(u);
            double un = au > 0.5 ? au - 0.5 : 0, uf = au + 0.5;
            if (un * un + vn * vn >= r2)
                continue; /* nearest point outside */
            float cov;
            if (uf * uf + vf * vf <= r2)
                cov = 1.0f; /* farthest corner inside */
            else {
                int hits = 0;
                for (int sy = 0; sy < RENDER_SUB; sy++) {
                    double w = v + off[sy];
                    for (int sx = 0; sx < RENDER_SUB; sx++) {
                        double z = u + off[sx];
                        hits += z * z + w * w < r2;
                    }
                }
                cov = (float)hits / (RENDER_SUB * RENDER_SUB);
            }
            float *px = &pupil[(size_t)iy * n + ix];
            if (subtract) /* an obstruction: take its coverage away */
                *px = *px - cov < 0.0f ? 0.0f : *px - cov;
            else
                *px = *px + cov > 1.0f ? 1.0f : *px + cov; /* shared edges */
        }
    }
}

int mask_render(const mask *m, float *pupil, int n, double dx_m,
                sl_err *err)
{
    if (!pupil || n < 1 || !(isfinite(dx_m) && dx_m > 0))
        return sl_seterr(err, SL_EINVAL,
                         "mask_render: bad grid (n = %d, dx = %g m)", n,
                         dx_m);
    /* pixel offsets from the centre run over [lo, hi], +-0.5 at the rims */
    double lo = -(double)(n / 2) - 0.5, hi = (double)(n - 1 - n / 2) + 0.5;
    int nd = m->nholes ? m->nholes : 1;
    double r = 0.5 * (m->nholes ? m->hole_d_m : m->diameter_m) / dx_m;
    for (int i = 0; i < nd; i++) {
        double hx = m->nholes ? m->x_m[i] / dx_m : 0;
        double hy = m->nholes ? m->y_m[i] / dx_m : 0;
        if (hx - r < lo || hx + r > hi || hy - r < lo || hy + r > hi)
            return sl_seterr(err, SL_ERANGE,
                             "mask_render: the %g m pupil ('%s') does not "
                             "fit a %dx%d grid of %g m pixels (%g m across): "
                             "%s (%g, %g) m reaches past the edge",
                             m->extent_m, m->name, n, n, dx_m, n * dx_m,
                             m->nholes ? "hole at" : "aperture centred at",
                             hx * dx_m, hy * dx_m);
    }
    memset(pupil, 0, (size_t)n * (size_t)n * sizeof *pupil);
    for (int i = 0; i < nd; i++)
        render_disk(pupil, n, m->nholes ? m->x_m[i] / dx_m : 0,
                    m->nholes ? m->y_m[i] / dx_m : 0, r, 0);
    if (m->obstruction > 0)
        render_disk(pupil, n, 0, 0, r * m->obstruction, 1);
    return SL_OK;
}
