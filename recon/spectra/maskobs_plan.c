/* maskobs_plan.c - where each baseline and triangle is sampled
 * (maskobs.h, Where): the clean pixels of every splodge and, per triangle,
 * the closing triple of them with the most transfer. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "maskobs_int.h"

/* Work done per triangle's search at most: a triangle whose legs' best
 * pixels do not close is searched further down the lists, and a
 * pathological one (huge splodges, all contaminated) gives up here. */
#define SEARCH_MAX 4000000L

typedef struct cand {
    int p, q;       /* true frequency, FFT index units */
    double t;       /* own transfer, DC = 1 */
} cand;

/* One baseline's splodge: its clean candidates by transfer, highest
 * first, and the same as a box of transfers (0: not clean) for lookups. */
typedef struct splodge {
    double cp, cq;  /* centre, FFT index units */
    cand *c;
    int nc;
    int p0, q0, bw, bh;
    float *box;
} splodge;

/* A splodge centre that may reach into the one being searched, with its
 * peak transfer in units of a baseline's (DC: nholes). */
typedef struct centre {
    double cp, cq, wt;
} centre;

typedef struct geom {
    int w, h, nholes, nb;
    double mx, my;  /* pupil metres per FFT index, along x and y */
    double d;       /* hole diameter [m] */
    double clean_max;
    splodge *sp;    /* nb, baseline (i, j) i < j in row order */
    centre *near;   /* 2 nb + 1 of scratch: the centres near one splodge */
    int nnear;
} geom;

/* Overlap of two holes of diameter d with centres t apart, over one
 * hole's area: 1 at t = 0, 0 from t = d. */
static double overlap_rel(double t, double d)
{
    double x = t / d;
    if (x >= 1.0)
        return 0.0;
    return 2.0 / M_PI * (acos(x) - x * sqrt(1.0 - x * x));
}

int maskobs_tap(int w, int h, int p, int q, mo_tap *tap)
{
    /* wrapped into (-w/2, w/2]: w/2 itself is the Nyquist column */
    int pw = ((p % w) + w) % w, qw = ((q % h) + h) % h;
    pw -= pw > w / 2 ? w : 0;
    qw -= qw > h / 2 ? h : 0;
    if ((w % 2 == 0 && pw == w / 2) || (h % 2 == 0 && qw == h / 2) ||
        (pw == 0 && qw == 0))
        return 0;
    int wc = w / 2 + 1;
    if (pw >= 0) {
        *tap = (mo_tap){((qw + h) % h) * wc + pw, 0};
    } else {
        *tap = (mo_tap){((-qw + h) % h) * wc - pw, 1};
    }
    return 1;
}

/* Distance in pupil metres from (p, q) to centre (cp, cq), the offset
 * wrapped onto the frame's period when wrap is set (aliases). */
static double dist_m(const geom *g, double p, double q, double cp, double cq,
                     int wrap)
{
    double dp = p - cp, dq = q - cq;
    if (wrap) {
        dp -= g->w * nearbyint(dp / g->w);
        dq -= g->h * nearbyint(dq / g->h);
    }
    return hypot(dp * g->mx, dq * g->my);
}

/* The centres (DC, the other baselines of both signs, baseline k's
 * mirror; aliased) within reach_m of baseline k's into g->near: only they
 * can add to its splodge's box.  Without this cut the search costs one
 * pass over all 2 nb + 1 centres per box pixel: 3.3 s for nrm17 at
 * 1024^2. */
static void near_centres(geom *g, int k, double reach_m)
{
    const splodge *o = &g->sp[k];
    g->nnear = 0;
    for (int l = -1; l < g->nb; l++)
        for (int sgn = 1; sgn >= -1; sgn -= 2) {
            if ((l == k && sgn > 0) || (l < 0 && sgn < 0))
                continue;
            double cp = l < 0 ? 0 : sgn * g->sp[l].cp, cq = l < 0 ? 0 : sgn * g->sp[l].cq;
            if (dist_m(g, cp, cq, o->cp, o->cq, 1) < reach_m)
                g->near[g->nnear++] = (centre){cp, cq, l < 0 ? g->nholes : 1};
        }
}

/* The transfer the centres in g->near add at (p, q), DC = 1. */
static double contamination(const geom *g, int p, int q)
{
    double c = 0;
    for (int i = 0; i < g->nnear; i++)
        c += g->near[i].wt * overlap_rel(dist_m(g, p, q, g->near[i].cp, g->near[i].cq, 1), g->d);
    return c / g->nholes;
}

static int by_transfer(const void *a, const void *b)
{
    double ta = ((const cand *)a)->t, tb = ((const cand *)b)->t;
    return (ta < tb) - (ta > tb);
}

/* Baseline k's clean candidates into its splodge (box and sorted list). */
static int find_clean(geom *g, int k)
{
    splodge *s = &g->sp[k];
    int rp = (int)ceil(g->d / g->mx) + 1, rq = (int)ceil(g->d / g->my) + 1;
    s->p0 = (int)floor(s->cp) - rp;
    s->q0 = (int)floor(s->cq) - rq;
    s->bw = 2 * rp + 2;
    s->bh = 2 * rq + 2;
    s->box = calloc((size_t)s->bw * s->bh, sizeof *s->box);
    s->c = malloc((size_t)s->bw * s->bh * sizeof *s->c);
    if (!s->box || !s->c)
        return SL_ENOMEM;
    double tmin = MASKOBS_MIN_TRANSFER / g->nholes;
    near_centres(g, k, g->d + hypot((rp + 2) * g->mx, (rq + 2) * g->my));
    for (int j = 0; j < s->bh; j++)
        for (int i = 0; i < s->bw; i++) {
            int p = s->p0 + i, q = s->q0 + j;
            mo_tap tap;
            double t = overlap_rel(dist_m(g, p, q, s->cp, s->cq, 0), g->d) / g->nholes;
            if (t < tmin || !maskobs_tap(g->w, g->h, p, q, &tap) ||
                contamination(g, p, q) > g->clean_max * t)
                continue;
            s->box[(size_t)j * s->bw + i] = (float)t;
            s->c[s->nc++] = (cand){p, q, t};
        }
    qsort(s->c, (size_t)s->nc, sizeof *s->c, by_transfer);
    return SL_OK;
}

/* Transfer of clean pixel (p, q) of splodge s, 0 when not clean. */
static double clean_at(const splodge *s, int p, int q)
{
    int i = p - s->p0, j = q - s->q0;
    if (i < 0 || j < 0 || i >= s->bw || j >= s->bh)
        return 0.0;
    return s->box[(size_t)j * s->bw + i];
}

/* Baseline index of holes i < j. */
static int bl_index(int n, int i, int j)
{
    return i * n - i * (i + 1) / 2 + (j - i - 1);
}

/* The closing triple (u1, u2, u1 + u2) with the largest transfer product,
 * by branch and bound down the sorted lists; 0 when there is none. */
static double best_triple(const splodge *a, const splodge *b,
                          const splodge *c, cand *u1, cand *u2)
{
    double best = 0, cmax = c->nc ? c->c[0].t : 0;
    long work = 0;
    for (int i = 0; i < a->nc && b->nc; i++) {
        if (a->c[i].t * b->c[0].t * cmax <= best)
            break;
        for (int k = 0; k < b->nc; k++) {
            double ab = a->c[i].t * b->c[k].t;
            if (ab * cmax <= best || ++work > SEARCH_MAX)
                break;
            double t3 = clean_at(c, a->c[i].p + b->c[k].p, a->c[i].q + b->c[k].q);
            if (t3 > 0 && ab * t3 > best) {
                best = ab * t3;
                *u1 = a->c[i];
                *u2 = b->c[k];
            }
        }
        if (work > SEARCH_MAX)
            break;
    }
    return best;
}

/* OIFITS (u, v) [m] of FFT frequency (p, q): east is -x (maskobs.h). */
static void uv_of(const geom *g, int p, int q, double *u_m, double *v_m)
{
    *u_m = -p * g->mx;
    *v_m = q * g->my;
}

static void plan_vis2(maskobs *m, geom *g)
{
    int n = g->nholes;
    for (int i = 0; i < n; i++)
        for (int j = i + 1; j < n; j++) {
            const splodge *s = &g->sp[bl_index(n, i, j)];
            if (!s->nc) {
                m->nvis2_lost++;
                continue;
            }
            maskobs_vis2 *v = &m->vis2[m->nvis2];
            memset(v, 0, sizeof *v);
            v->sta[0] = i, v->sta[1] = j;
            v->p = s->c[0].p, v->q = s->c[0].q;
            v->transfer = s->c[0].t;
            uv_of(g, v->p, v->q, &v->u_m, &v->v_m);
            maskobs_tap(g->w, g->h, v->p, v->q, &m->vtap[m->nvis2++]);
        }
}

static void plan_t3(maskobs *m, geom *g)
{
    int n = g->nholes;
    for (int i = 0; i < n; i++)
        for (int j = i + 1; j < n; j++)
            for (int k = j + 1; k < n; k++) {
                cand u1 = {0, 0, 0}, u2 = {0, 0, 0};
                double t = best_triple(&g->sp[bl_index(n, i, j)], &g->sp[bl_index(n, j, k)],
                                       &g->sp[bl_index(n, i, k)], &u1, &u2);
                if (!(t > 0)) {
                    m->nt3_lost++;
                    continue;
                }
                maskobs_t3 *r = &m->t3[m->nt3];
                memset(r, 0, sizeof *r);
                r->sta[0] = i, r->sta[1] = j, r->sta[2] = k;
                r->p1 = u1.p, r->q1 = u1.q, r->p2 = u2.p, r->q2 = u2.q;
                uv_of(g, u1.p, u1.q, &r->u1_m, &r->v1_m);
                uv_of(g, u2.p, u2.q, &r->u2_m, &r->v2_m);
                m->t3_transfer[m->nt3] = t;
                mo_tap *tp = &m->ttap[3 * (size_t)m->nt3++];
                maskobs_tap(g->w, g->h, u1.p, u1.q, &tp[0]);
                maskobs_tap(g->w, g->h, u2.p, u2.q, &tp[1]);
                maskobs_tap(g->w, g->h, u1.p + u2.p, u1.q + u2.q, &tp[2]);
            }
}

static void free_geom(geom *g)
{
    for (int l = 0; g->sp && l < g->nb; l++) {
        free(g->sp[l].c);
        free(g->sp[l].box);
    }
    free(g->sp);
    free(g->near);
}

int maskobs_plan(maskobs *m, const double *x_m, const double *y_m,
                 double hole_diameter_m)
{
    int n = m->nholes, rc = SL_OK;
    double s_rad = m->o.plate_scale_arcsec * M_PI / (180.0 * 3600.0);
    geom g = {m->w, m->h, n, n * (n - 1) / 2, m->o.wavelength_m / (s_rad * m->w),
              m->o.wavelength_m / (s_rad * m->h), hole_diameter_m,
              m->o.clean_max > 0 ? m->o.clean_max : MASKOBS_CLEAN_MAX, NULL, NULL, 0};
    long ntri = (long)n * (n - 1) * (n - 2) / 6;
    g.sp = calloc((size_t)g.nb, sizeof *g.sp);
    g.near = malloc((2 * (size_t)g.nb + 1) * sizeof *g.near);
    m->vis2 = malloc((size_t)g.nb * sizeof *m->vis2);
    m->vtap = malloc((size_t)g.nb * sizeof *m->vtap);
    m->t3 = malloc((size_t)ntri * sizeof *m->t3);
    m->t3_transfer = malloc((size_t)ntri * sizeof *m->t3_transfer);
    m->ttap = malloc((size_t)ntri * 3 * sizeof *m->ttap);
    if (!g.sp || !g.near || !m->vis2 || !m->vtap || !m->t3 || !m->t3_transfer || !m->ttap) {
        rc = sl_seterr(&m->err, SL_ENOMEM, "mask observables: out of memory "
                       "for %d holes", n);
        goto free_g;
    }
    for (int i = 0; i < n; i++)
        for (int j = i + 1; j < n; j++) {
            splodge *s = &g.sp[bl_index(n, i, j)];
            s->cp = (x_m[j] - x_m[i]) / g.mx;
            s->cq = (y_m[j] - y_m[i]) / g.my;
        }
    for (int l = 0; l < g.nb; l++)
        if (find_clean(&g, l) != SL_OK) {
            rc = sl_seterr(&m->err, SL_ENOMEM, "mask observables: out of "
                           "memory for the splodges");
            goto free_g;
        }
    plan_vis2(m, &g);
    plan_t3(m, &g);
    if (m->nt3 == 0)
        rc = sl_seterr(&m->err, SL_EDATA, "mask observables: none of the %ld "
                       "hole triangles has a clean pixel in all three splodges "
                       "(%d of %d baselines lost; hole %.3g m, %.3g m of pupil per "
                       "FFT pixel)", ntri, m->nvis2_lost, g.nb, g.d, g.mx);
free_g:
    free_geom(&g);
    return rc;
}
