/* scene.c - see scene.h. */
#include "scene.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

struct scene {
    scene_comp *comp;
    int n, cap;
    char name[128];
};

scene *scene_new(void)
{
    scene *s = calloc(1, sizeof *s);
    if (s)
        snprintf(s->name, sizeof s->name, "custom");
    return s;
}

void scene_free(scene *s)
{
    if (!s)
        return;
    free(s->comp);
    free(s);
}

void scene_set_name(scene *s, const char *name)
{
    snprintf(s->name, sizeof s->name, "%s", name);
}

const char *scene_name(const scene *s) { return s->name; }
int scene_ncomp(const scene *s) { return s->n; }
const scene_comp *scene_comp_at(const scene *s, int i) { return &s->comp[i]; }

int scene_add(scene *s, const scene_comp *c, sl_err *err)
{
    if (!(isfinite(c->x_arcsec) && isfinite(c->y_arcsec) && isfinite(c->flux)))
        return sl_seterr(err, SL_EINVAL, "scene component has a non-finite "
                         "position or flux");
    if (c->flux < 0)
        return sl_seterr(err, SL_EINVAL, "scene component flux %g is negative",
                         c->flux);
    if (c->kind == SCENE_DISK &&
        !(c->radius_arcsec > 0 && isfinite(c->radius_arcsec)))
        return sl_seterr(err, SL_EINVAL, "disk radius %g arcsec must be > 0",
                         c->radius_arcsec);
    if (c->kind == SCENE_DISK && !(c->limb_u >= 0 && c->limb_u <= 1))
        return sl_seterr(err, SL_EINVAL, "limb darkening u = %g must lie in "
                         "[0, 1]", c->limb_u);
    if (c->kind == SCENE_DISK && c->band_amp != 0 &&
        !(c->band_period_arcsec > 0 && fabs(c->band_amp) <= 1))
        return sl_seterr(err, SL_EINVAL, "bands need |amplitude| <= 1 and a "
                         "positive period");
    if (s->n == s->cap) {
        int cap = s->cap ? 2 * s->cap : 8;
        scene_comp *p = realloc(s->comp, (size_t)cap * sizeof *p);
        if (!p)
            return sl_seterr(err, SL_ENOMEM, "out of memory growing scene");
        s->comp = p;
        s->cap = cap;
    }
    s->comp[s->n++] = *c;
    return SL_OK;
}

double scene_total_flux(const scene *s)
{
    double f = 0;
    for (int i = 0; i < s->n; i++)
        f += s->comp[i].flux;
    return f;
}

double scene_radius_arcsec(const scene *s)
{
    double r = 0;
    for (int i = 0; i < s->n; i++) {
        const scene_comp *c = &s->comp[i];
        double d = hypot(c->x_arcsec, c->y_arcsec);
        if (c->kind == SCENE_DISK)
            d += c->radius_arcsec;
        if (d > r)
            r = d;
    }
    return r;
}

void scene_pa_offset(double sep, double pa_deg, double *dx, double *dy)
{
    double pa = pa_deg * M_PI / 180.0;
    *dx = -sep * sin(pa);
    *dy = sep * cos(pa);
}

static int add_point(scene *s, double x, double y, double f, sl_err *err)
{
    scene_comp c = {.kind = SCENE_POINT, .x_arcsec = x, .y_arcsec = y,
                    .flux = f};
    return scene_add(s, &c, err);
}

int scene_binary(scene **out, double sep_arcsec, double pa_deg, double dm_mag,
                 sl_err *err)
{
    *out = NULL;
    if (!(sep_arcsec >= 0 && isfinite(sep_arcsec)))
        return sl_seterr(err, SL_EINVAL, "binary separation %g arcsec must be "
                         ">= 0", sep_arcsec);
    if (!(dm_mag >= 0 && dm_mag <= 15))
        return sl_seterr(err, SL_EINVAL, "binary dm %g mag must lie in "
                         "[0, 15] (the companion is the fainter star)", dm_mag);
    if (!isfinite(pa_deg))
        return sl_seterr(err, SL_EINVAL, "binary position angle is not finite");
    scene *s = scene_new();
    if (!s)
        return sl_seterr(err, SL_ENOMEM, "out of memory");
    double ratio = pow(10.0, -0.4 * dm_mag), dx, dy;
    scene_pa_offset(sep_arcsec, pa_deg, &dx, &dy);
    /* Flux centroid at the field centre: reconstructions centre on it. */
    double w2 = ratio / (1.0 + ratio);
    int rc = add_point(s, -dx * w2, -dy * w2, 1.0, err);
    if (rc == SL_OK)
        rc = add_point(s, dx * (1 - w2), dy * (1 - w2), ratio, err);
    if (rc != SL_OK) {
        scene_free(s);
        return rc;
    }
    scene_set_name(s, "binary");
    *out = s;
    return SL_OK;
}

/* A compact six-star group: positions within 0.6 arcsec (6 lambda/B at
 * 500 nm and 1 m) and brightness ratios 1 : 0.8 : 0.6 : 0.5 : 0.4 : 0.3,
 * chosen so that no separation is below the mask's resolution. */
static const double six_star[6][3] = {
    {0.00, 0.00, 1.0},   {0.35, 0.20, 0.8},  {-0.30, 0.38, 0.6},
    {-0.42, -0.25, 0.5}, {0.15, -0.48, 0.4}, {0.55, -0.18, 0.3},
};

static int scene_extended(scene *s, sl_err *err)
{
    /* A Jupiter-like disk 0.55 arcsec in radius: limb darkened, banded. */
    scene_comp c = {.kind = SCENE_DISK, .radius_arcsec = 0.55, .flux = 1.0,
                    .limb_u = 0.5, .band_amp = 0.35,
                    .band_period_arcsec = 0.3};
    return scene_add(s, &c, err);
}

int scene_named(scene **out, const char *name, double sep_arcsec,
                double pa_deg, double dm_mag, sl_err *err)
{
    *out = NULL;
    if (strcmp(name, "binary") == 0)
        return scene_binary(out, sep_arcsec, pa_deg, dm_mag, err);
    scene *s = scene_new();
    if (!s)
        return sl_seterr(err, SL_ENOMEM, "out of memory");
    int rc = SL_OK;
    if (strcmp(name, "point") == 0) {
        rc = add_point(s, 0, 0, 1, err);
    } else if (strcmp(name, "six-star") == 0) {
        double cx = 0, cy = 0, f = 0;
        for (int i = 0; i < 6; i++) {
            cx += six_star[i][0] * six_star[i][2];
            cy += six_star[i][1] * six_star[i][2];
            f += six_star[i][2];
        }
        for (int i = 0; i < 6 && rc == SL_OK; i++)
            rc = add_point(s, six_star[i][0] - cx / f,
                           six_star[i][1] - cy / f, six_star[i][2], err);
    } else if (strcmp(name, "extended") == 0) {
        rc = scene_extended(s, err);
    } else {
        rc = sl_seterr(err, SL_EINVAL, "unknown scene '%s' (known: point, "
                       "binary, six-star, extended, or a scene file)", name);
    }
    if (rc != SL_OK) {
        scene_free(s);
        return rc;
    }
    scene_set_name(s, name);
    *out = s;
    return SL_OK;
}

static int parse_line(scene *s, const char *path, int lineno, char *line,
                      sl_err *err)
{
    char kind[16], extra[2];
    scene_comp c = {0};
    int n;
    if (sscanf(line, "%15s", kind) != 1)
        return SL_OK; /* blank */
    if (strcmp(kind, "point") == 0) {
        n = sscanf(line, "%*s %lf %lf %lf %1s", &c.x_arcsec, &c.y_arcsec,
                   &c.flux, extra);
        if (n != 3)
            return sl_seterr(err, SL_EFORMAT, "%s:%d: expected 'point "
                             "X_ARCSEC Y_ARCSEC FLUX'", path, lineno);
        c.kind = SCENE_POINT;
    } else if (strcmp(kind, "disk") == 0) {
        n = sscanf(line, "%*s %lf %lf %lf %lf %lf %lf %lf %1s", &c.x_arcsec,
                   &c.y_arcsec, &c.radius_arcsec, &c.flux, &c.limb_u,
                   &c.band_amp, &c.band_period_arcsec, extra);
        if (n != 4 && n != 5 && n != 7)
            return sl_seterr(err, SL_EFORMAT, "%s:%d: expected 'disk X_ARCSEC "
                             "Y_ARCSEC RADIUS_ARCSEC FLUX [LIMB_U [BAND_AMP "
                             "BAND_PERIOD_ARCSEC]]'", path, lineno);
        c.kind = SCENE_DISK;
    } else {
        return sl_seterr(err, SL_EFORMAT, "%s:%d: unknown component '%s' "
                         "(expected point or disk)", path, lineno, kind);
    }
    int rc = scene_add(s, &c, err);
    if (rc != SL_OK) {
        char msg[SL_ERRMSG_MAX];
        snprintf(msg, sizeof msg, "%s", err ? err->msg : "");
        return sl_seterr(err, rc, "%s:%d: %s", path, lineno, msg);
    }
    return SL_OK;
}

int scene_read(scene **out, const char *path, sl_err *err)
{
    int rc = SL_OK, lineno = 0;
    char line[1024];
    *out = NULL;
    FILE *f = fopen(path, "r");
    if (!f)
        return sl_seterr(err, SL_EIO, "cannot open scene file %s: %s", path,
                         strerror(errno));
    scene *s = scene_new();
    if (!s) {
        rc = sl_seterr(err, SL_ENOMEM, "out of memory");
        goto close_file;
    }
    while (fgets(line, sizeof line, f)) {
        lineno++;
        char *hash = strchr(line, '#');
        if (hash)
            *hash = '\0';
        rc = parse_line(s, path, lineno, line, err);
        if (rc != SL_OK)
            goto free_scene;
    }
    if (ferror(f)) {
        rc = sl_seterr(err, SL_EIO, "error reading %s", path);
        goto free_scene;
    }
    if (s->n == 0) {
        rc = sl_seterr(err, SL_EFORMAT, "%s: no point or disk components",
                       path);
        goto free_scene;
    }
    scene_set_name(s, path);
    *out = s;
    goto close_file;
free_scene:
    scene_free(s);
close_file:
    fclose(f);
    return rc;
}

static void splat_point(float *img, int w, int h, double px, double py,
                        double flux)
{
    /* A point at px <= -1 or >= w touches no pixel; skipping it also keeps
     * the int conversion below in range (found by fuzzing: 1e300). */
    if (!(px > -1 && px < w && py > -1 && py < h))
        return;
    int x0 = (int)floor(px), y0 = (int)floor(py);
    double fx = px - x0, fy = py - y0;
    double wts[4] = {(1 - fx) * (1 - fy), fx * (1 - fy), (1 - fx) * fy,
                     fx * fy};
    for (int j = 0; j < 4; j++) {
        int x = x0 + (j & 1), y = y0 + (j >> 1);
        if (x >= 0 && x < w && y >= 0 && y < h)
            img[(size_t)y * w + x] += (float)(flux * wts[j]);
    }
}

/* Unnormalised surface brightness of a disk at offset (dx, dy) arcsec. */
static double disk_brightness(const scene_comp *c, double dx, double dy)
{
    /* Scaled before squaring: dx * dx overflows to Inf for a disk of
     * 1e300 arcsec, and Inf / Inf made NaN pixels (found by fuzzing). */
    double u = dx / c->radius_arcsec, v = dy / c->radius_arcsec;
    double r2 = u * u + v * v;
    if (r2 >= 1)
        return 0;
    double mu = sqrt(1 - r2);
    double b = 1 - c->limb_u * (1 - mu);
    if (c->band_amp != 0)
        b *= 1 + c->band_amp * cos(2 * M_PI * dy / c->band_period_arcsec);
    return b;
}

/* Cost: O(disk area in pixels * 16), at most SCENE_MAX_DISK_RADIUS_PX^2
 * * 64 brightness samples.  SL_ERANGE (nothing drawn) for a disk larger
 * than that; a disk wholly off the grid is skipped. */
static int render_disk(const scene_comp *c, float *img, int w, int h,
                       double psx, double psy)
{
    const int ss = 4;
    double cx = w / 2 + c->x_arcsec / psx, cy = h / 2 + c->y_arcsec / psy;
    double rpx = c->radius_arcsec / psx + 1, rpy = c->radius_arcsec / psy + 1;
    /* The box [floor(cx - rp), ceil(cx + rp)] misses the grid: nothing to
     * draw.  Otherwise |cx|, |cy| <= grid + rp, so with the cap on rp every
     * bound below fits an int (fuzzing found 1e300 arcsec offsets). */
    if (cx + rpx < -1 || cx - rpx > w || cy + rpy < -1 || cy - rpy > h)
        return SL_OK;
    if (!(rpx <= SCENE_MAX_DISK_RADIUS_PX && rpy <= SCENE_MAX_DISK_RADIUS_PX))
        return SL_ERANGE;
    int x0 = (int)floor(cx - rpx), x1 = (int)ceil(cx + rpx);
    int y0 = (int)floor(cy - rpy), y1 = (int)ceil(cy + rpy);
    double total = 0;
    /* Two passes: the normalisation uses the whole disk, even if clipped. */
    for (int pass = 0; pass < 2; pass++) {
        double scale = pass ? c->flux / total : 0;
        for (int y = y0; y <= y1; y++)
            for (int x = x0; x <= x1; x++) {
                double sum = 0;
                for (int sy = 0; sy < ss; sy++)
                    for (int sx = 0; sx < ss; sx++) {
                        double dx = (x + (sx + 0.5) / ss - 0.5 - cx) * psx;
                        double dy = (y + (sy + 0.5) / ss - 0.5 - cy) * psy;
                        sum += disk_brightness(c, dx, dy);
                    }
                if (!pass)
                    total += sum;
                else if (x >= 0 && x < w && y >= 0 && y < h)
                    img[(size_t)y * w + x] += (float)(sum * scale);
            }
        if (total <= 0)
            return SL_OK;
    }
    return SL_OK;
}

int scene_render(const scene *s, float *img, int w, int h,
                 double pscale_arcsec, int omit_points)
{
    return scene_render_rect(s, img, w, h, pscale_arcsec, pscale_arcsec,
                             omit_points);
}

int scene_render_rect(const scene *s, float *img, int w, int h,
                      double psx_arcsec, double psy_arcsec, int omit_points)
{
    /* Inf: 0 * Inf offsets would make NaN pixels */
    if (!(psx_arcsec > 0 && isfinite(psx_arcsec)) ||
        !(psy_arcsec > 0 && isfinite(psy_arcsec)) || w <= 0 || h <= 0)
        return SL_EINVAL;
    int rc = SL_OK;
    memset(img, 0, (size_t)w * h * sizeof *img);
    for (int i = 0; i < s->n && rc == SL_OK; i++) {
        const scene_comp *c = &s->comp[i];
        if (c->kind == SCENE_POINT) {
            if (!omit_points)
                splat_point(img, w, h, w / 2 + c->x_arcsec / psx_arcsec,
                            h / 2 + c->y_arcsec / psy_arcsec, c->flux);
        } else {
            rc = render_disk(c, img, w, h, psx_arcsec, psy_arcsec);
        }
    }
    if (rc != SL_OK) /* a partial image must not pass for the scene */
        memset(img, 0, (size_t)w * h * sizeof *img);
    return rc;
}
