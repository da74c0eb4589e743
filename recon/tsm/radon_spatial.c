/* radon_spatial.c - see radon_spatial.h.
 *
 * Projector geometry.  For angle k, lattice point (a, b) is at
 * C + a n + b m with n = (cs[k], sn[k]), m = (-sn[k], cs[k]), and
 * proj[k][wrap(a + ns/2)] sums its bilinear samples over b (ray a).  For
 * the partner k' = k + K/2 (theta + 90 deg) n' = m and m' = -n, so the
 * point C + a' n' + b' m' is lattice point (a, b) = (-b', a'): ray a' of k'
 * is the column b = a' of k's lattice.  (cs, sn of k' are those of k
 * rotated to within 1e-16, which moves the points by 1e-14 px.)
 *
 * A pass walks lines along e1 (inner index i) at outer index o:
 * P(o, i) = C + o e2 + i e1.  The line sum goes to bin o of projection
 * krow, the sample at i to bin i of projection kcol:
 *     |cos| >= |sin|: e1 = n, e2 = m: krow = k', kcol = k;
 *     else:           e1 = m, e2 = n: krow = k,  kcol = k'.
 * Each line is clipped to the open rectangle (-1, w) x (-1, h), beyond
 * which all four taps lie in the zero border (as the ray-by-ray original
 * did), and its points are stepped in 32.32 fixed point from a start
 * rounded once: after 300 steps the point is within 4e-8 px of the exact
 * one, so the float weights are exact to their rounding.
 */
#include "radon_spatial.h"

#include "radon_spatial_int.h"

#include <math.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>

double radon_window_gain(radon_window win, double f, double fc)
{
    if (f > fc)
        return 0.0;
    double x = f / fc;
    switch (win) {
    case RADON_WIN_SHEPP_LOGAN:
        return x > 0 ? sin(M_PI_2 * x) / (M_PI_2 * x) : 1.0;
    case RADON_WIN_COSINE: return cos(M_PI_2 * x);
    case RADON_WIN_HANN: return 0.5 * (1.0 + cos(M_PI * x));
    default: return 1.0;
    }
}

static int wrap(int i, int n) { i %= n; return i < 0 ? i + n : i; }

/* Floats of the row pairs: the frame in a 2-pixel zero border. */
static size_t rows_n(const radon_spatial *sp) { return 2 * ((size_t)sp->w + 4) * (sp->h + 4); }

int radon_spatial_can_project(const radon_spatial *sp) { return sp->rp != NULL; }

void radon_spatial_free(radon_spatial *sp)
{
    if (!sp)
        return;
    if (sp->l_r2c)
        fftwf_destroy_plan(sp->l_r2c);
    if (sp->u_c2r)
        fftwf_destroy_plan(sp->u_c2r);
    void *fb[] = {sp->l_in, sp->u_out, sp->l_spec, sp->u_spec};
    for (size_t i = 0; i < sizeof fb / sizeof fb[0]; i++)
        fftwf_free(fb[i]);
    void *mb[] = {sp->rp, sp->pass, sp->line, sp->cols, sp->bin, sp->qall, sp->ramp};
    for (size_t i = 0; i < sizeof mb / sizeof mb[0]; i++)
        free(mb[i]);
    free(sp);
}

/* ---- projector tables ---------------------------------------------------- */

/* Lines of one pass: inner step e1, outer step e2; returns the lines
 * written at sp->line + nl. */
static int pass_lines(radon_spatial *sp, int nl, double e1x, double e1y,
                      double e2x, double e2y)
{
    int w = sp->w, h = sp->h, half = sp->nd / 2;
    double cx = w / 2, cy = h / 2;
    for (int o = -half; o <= half; o++) {
        /* Keep the i where the point is in (-1, w) x (-1, h). */
        double x0 = cx + o * e2x, y0 = cy + o * e2y, lo = -half, hi = half;
        if (fabs(e1x) > 1e-12) {
            double a = (-1 - x0) / e1x, b = (w - x0) / e1x;
            lo = fmax(lo, fmin(a, b)), hi = fmin(hi, fmax(a, b));
        } else if (x0 <= -1 || x0 >= w)
            continue;
        if (fabs(e1y) > 1e-12) {
            double a = (-1 - y0) / e1y, b = (h - y0) / e1y;
            lo = fmax(lo, fmin(a, b)), hi = fmin(hi, fmax(a, b));
        } else if (y0 <= -1 || y0 >= h)
            continue;
        int i0 = (int)ceil(lo), i1 = (int)floor(hi);
        if (i1 < i0)
            continue;
        sp_line *l = sp->line + nl++;
        l->x = llround(ldexp(x0 + i0 * e1x + 2, 32));
        l->y = llround(ldexp(y0 + i0 * e1y + 2, 32));
        l->i0 = i0 + half, l->n = i1 - i0 + 1, l->o = o + half;
    }
    return nl;
}

static int build_projector(radon_spatial *sp)
{
    int K = sp->nang, paired = K % 2 == 0, np = paired ? K / 2 : K;
    int nd = (int)ceil(hypot(sp->w, sp->h)) + 4;
    sp->nd = nd += nd & 1;
    sp->rp = calloc(rows_n(sp), sizeof *sp->rp);   /* the border stays 0 */
    sp->pass = malloc(np * sizeof *sp->pass);
    sp->line = malloc((size_t)np * (nd + 1) * sizeof *sp->line);
    sp->cols = malloc((size_t)sp->nthr * (nd + 9) * sizeof *sp->cols);
    sp->bin = malloc((nd + 1) * sizeof *sp->bin);
    if (!sp->rp || !sp->pass || !sp->line || !sp->cols || !sp->bin)
        return SL_ENOMEM;
    for (int i = 0; i <= nd; i++)
        sp->bin[i] = wrap(i - nd / 2 + sp->ns / 2, sp->ns);
    int nl = 0;
    for (int k = 0; k < np; k++) {
        double c = sp->cs[k], s = sp->sn[k];
        int partner = paired ? k + K / 2 : -1;
        sp_pass *p = sp->pass + k;
        double e1x = -s, e1y = c, e2x = c, e2y = s;   /* e1 = m, e2 = n */
        p->krow = k, p->kcol = partner;
        if (fabs(c) >= fabs(s)) {
            e1x = c, e1y = s, e2x = -s, e2y = c;      /* e1 = n, e2 = m */
            p->krow = partner, p->kcol = k;
        }
        p->ex = llround(ldexp(e1x, 32));
        p->ey = llround(ldexp(e1y, 32));
        p->l0 = nl;
        nl = pass_lines(sp, nl, e1x, e1y, e2x, e2y);
        p->l1 = nl;
    }
    sp->npass = np, sp->nline = nl;
    radon_spatial_set_simd(sp, -1);
    return SL_OK;
}

/* ---- projector ------------------------------------------------------------ */

/* Bilinear sample at fixed-point (x, y) (> 0: inside the padded frame);
 * its four taps are rp[2 i .. 2 i + 3] for pixel index i. */
static inline float sample(const float *rp, size_t pw, int64_t x, int64_t y)
{
    const float *q = rp + 2 * ((size_t)(x >> 32) + (size_t)(y >> 32) * pw);
    float fx = (float)(int32_t)((uint32_t)x >> 8) * 0x1p-24f;
    float fy = (float)(int32_t)((uint32_t)y >> 8) * 0x1p-24f;
    float top = q[0] + fx * (q[2] - q[0]);
    float bot = q[1] + fx * (q[3] - q[1]);
    return top + fy * (bot - top);
}

/* Every path sums a line in the same order: point i into lane i % 8, then
 * the eight lanes pairwise; so SIMD and portable code give the same bits.
 * The SIMD loops run whole blocks of 8, the last one with the lanes past
 * the line's end pointed at pixel 0 of the zero border: they add +0 to
 * their lane and to col (cols has 8 floats of slack). */
static inline float lanes_sum(const float *a)
{
    return ((a[0] + a[1]) + (a[2] + a[3])) + ((a[4] + a[5]) + (a[6] + a[7]));
}

/* One line: adds each sample to col[i], returns their sum. */
static float line_portable(const float *rp, size_t pw, const sp_line *l, int64_t ex,
                           int64_t ey, float *col)
{
    float lane[8] = {0};
    int64_t x = l->x, y = l->y;
    for (int i = 0; i < l->n; i++, x += ex, y += ey) {
        float v = sample(rp, pw, x, y);
        lane[i % 8] += v;
        col[i] += v;
    }
    return lanes_sum(lane);
}

#if SP_SSE2
/* Four samples at x = (xa0, xa1, xb0, xb1), likewise y; lanes where keep
 * is 0 read pixel 0 (border).  The integer parts combine into the pixel
 * index with one pmaddwd (lanes ix | iy << 16, both < 2^15: see
 * set_simd), the weights are the fractions' top 24 bits as in sample(),
 * and a lane's four taps are one load, transposed. */
static inline __m128 quad_sse2(const float *rp, __m128i xa, __m128i xb, __m128i ya,
                               __m128i yb, __m128i madd, __m128i keep)
{
    const __m128 scale = _mm_set1_ps(0x1p-24f);
    __m128 xa_ = _mm_castsi128_ps(xa), xb_ = _mm_castsi128_ps(xb);
    __m128 ya_ = _mm_castsi128_ps(ya), yb_ = _mm_castsi128_ps(yb);
    __m128i ix = _mm_castps_si128(_mm_shuffle_ps(xa_, xb_, _MM_SHUFFLE(3, 1, 3, 1)));
    __m128i iy = _mm_castps_si128(_mm_shuffle_ps(ya_, yb_, _MM_SHUFFLE(3, 1, 3, 1)));
    __m128i fxi = _mm_castps_si128(_mm_shuffle_ps(xa_, xb_, _MM_SHUFFLE(2, 0, 2, 0)));
    __m128i fyi = _mm_castps_si128(_mm_shuffle_ps(ya_, yb_, _MM_SHUFFLE(2, 0, 2, 0)));
    __m128 fx = _mm_mul_ps(_mm_cvtepi32_ps(_mm_srli_epi32(fxi, 8)), scale);
    __m128 fy = _mm_mul_ps(_mm_cvtepi32_ps(_mm_srli_epi32(fyi, 8)), scale);
    __m128i idx = _mm_madd_epi16(_mm_or_si128(ix, _mm_slli_epi32(iy, 16)), madd);
    idx = _mm_and_si128(idx, keep);
    uint64_t i01 = (uint64_t)_mm_cvtsi128_si64(idx);
    uint64_t i23 = (uint64_t)_mm_cvtsi128_si64(_mm_unpackhi_epi64(idx, idx));
    __m128 q00 = _mm_loadu_ps(rp + 2 * (size_t)(uint32_t)i01);
    __m128 q10 = _mm_loadu_ps(rp + 2 * (size_t)(i01 >> 32));
    __m128 q01 = _mm_loadu_ps(rp + 2 * (size_t)(uint32_t)i23);
    __m128 q11 = _mm_loadu_ps(rp + 2 * (size_t)(i23 >> 32));
    _MM_TRANSPOSE4_PS(q00, q10, q01, q11);   /* lanes -> taps (0,0) (0,1) (1,0) (1,1) */
    __m128 top = _mm_add_ps(q00, _mm_mul_ps(fx, _mm_sub_ps(q01, q00)));
    __m128 bot = _mm_add_ps(q10, _mm_mul_ps(fx, _mm_sub_ps(q11, q10)));
    return _mm_add_ps(top, _mm_mul_ps(fy, _mm_sub_ps(bot, top)));
}

static float line_sse2(const float *rp, size_t pw, const sp_line *l, int64_t ex,
                       int64_t ey, float *col)
{
    int64_t x = l->x, y = l->y;
    __m128i xa = _mm_set_epi64x(x + ex, x), xb = _mm_set_epi64x(x + 3 * ex, x + 2 * ex);
    __m128i ya = _mm_set_epi64x(y + ey, y), yb = _mm_set_epi64x(y + 3 * ey, y + 2 * ey);
    const __m128i dx = _mm_set1_epi64x(4 * ex), dy = _mm_set1_epi64x(4 * ey);
    const __m128i madd = _mm_set1_epi32((int)(1u | (uint32_t)pw << 16));
    const __m128i iota = _mm_set_epi32(3, 2, 1, 0);
    const int n = l->n;   /* (col stores could alias *l) */
    __m128i keep0 = _mm_set1_epi32(-1), keep1 = keep0;
    __m128 acc0 = _mm_setzero_ps(), acc1 = _mm_setzero_ps();
    for (int i = 0; i < n; i += 8) {   /* lanes 0-3 into acc0, 4-7 acc1 */
        if (n - i < 8) {
            keep0 = _mm_cmpgt_epi32(_mm_set1_epi32(n - i), iota);
            keep1 = _mm_cmpgt_epi32(_mm_set1_epi32(n - i - 4), iota);
        }
        __m128 v = quad_sse2(rp, xa, xb, ya, yb, madd, keep0);
        acc0 = _mm_add_ps(acc0, v);
        _mm_storeu_ps(col + i, _mm_add_ps(_mm_loadu_ps(col + i), v));
        xa = _mm_add_epi64(xa, dx), xb = _mm_add_epi64(xb, dx);
        ya = _mm_add_epi64(ya, dy), yb = _mm_add_epi64(yb, dy);
        v = quad_sse2(rp, xa, xb, ya, yb, madd, keep1);
        acc1 = _mm_add_ps(acc1, v);
        _mm_storeu_ps(col + i + 4, _mm_add_ps(_mm_loadu_ps(col + i + 4), v));
        xa = _mm_add_epi64(xa, dx), xb = _mm_add_epi64(xb, dx);
        ya = _mm_add_epi64(ya, dy), yb = _mm_add_epi64(yb, dy);
    }
    float lane[8];
    _mm_storeu_ps(lane, acc0), _mm_storeu_ps(lane + 4, acc1);
    return lanes_sum(lane);
}

/* The same eight at a time.  x, y sit in 64-bit lanes (0, 1, 4, 5) and
 * (2, 3, 6, 7) so that the in-lane shuffles put them in order. */
__attribute__((target("avx2")))
static float line_avx2(const float *rp, size_t pw, const sp_line *l, int64_t ex,
                       int64_t ey, float *col)
{
    int64_t x = l->x, y = l->y;
    __m256i xa = _mm256_set_epi64x(x + 5 * ex, x + 4 * ex, x + ex, x);
    __m256i xb = _mm256_set_epi64x(x + 7 * ex, x + 6 * ex, x + 3 * ex, x + 2 * ex);
    __m256i ya = _mm256_set_epi64x(y + 5 * ey, y + 4 * ey, y + ey, y);
    __m256i yb = _mm256_set_epi64x(y + 7 * ey, y + 6 * ey, y + 3 * ey, y + 2 * ey);
    const __m256i dx = _mm256_set1_epi64x(8 * ex), dy = _mm256_set1_epi64x(8 * ey);
    const __m256i madd = _mm256_set1_epi32((int)(1u | (uint32_t)pw << 16));
    const __m256i iota = _mm256_set_epi32(7, 6, 5, 4, 3, 2, 1, 0);
    const int n = l->n;   /* (col stores could alias *l) */
    const __m256 scale = _mm256_set1_ps(0x1p-24f);
    __m256i keep = _mm256_set1_epi32(-1);
    __m256 acc = _mm256_setzero_ps();
    for (int i = 0; i < n; i += 8) {
        if (n - i < 8)
            keep = _mm256_cmpgt_epi32(_mm256_set1_epi32(n - i), iota);
        __m256 xa_ = _mm256_castsi256_ps(xa), xb_ = _mm256_castsi256_ps(xb);
        __m256 ya_ = _mm256_castsi256_ps(ya), yb_ = _mm256_castsi256_ps(yb);
        __m256i ix = _mm256_castps_si256(_mm256_shuffle_ps(xa_, xb_, _MM_SHUFFLE(3, 1, 3, 1)));
        __m256i iy = _mm256_castps_si256(_mm256_shuffle_ps(ya_, yb_, _MM_SHUFFLE(3, 1, 3, 1)));
        __m256i fxi = _mm256_castps_si256(_mm256_shuffle_ps(xa_, xb_, _MM_SHUFFLE(2, 0, 2, 0)));
        __m256i fyi = _mm256_castps_si256(_mm256_shuffle_ps(ya_, yb_, _MM_SHUFFLE(2, 0, 2, 0)));
        __m256 fx = _mm256_mul_ps(_mm256_cvtepi32_ps(_mm256_srli_epi32(fxi, 8)), scale);
        __m256 fy = _mm256_mul_ps(_mm256_cvtepi32_ps(_mm256_srli_epi32(fyi, 8)), scale);
        __m256i idx = _mm256_madd_epi16(_mm256_or_si256(ix, _mm256_slli_epi32(iy, 16)), madd);
        idx = _mm256_and_si256(idx, keep);
        __m128i lo = _mm256_castsi256_si128(idx), hi = _mm256_extracti128_si256(idx, 1);
        uint64_t i01 = (uint64_t)_mm_cvtsi128_si64(lo), i23 = (uint64_t)_mm_extract_epi64(lo, 1);
        uint64_t i45 = (uint64_t)_mm_cvtsi128_si64(hi), i67 = (uint64_t)_mm_extract_epi64(hi, 1);
        /* lane k's taps are 4 floats at rp + 2 i_k; lanes k, k + 4 share
         * a register, then an in-lane 4x4 transpose */
#define TAPS(a, b) _mm256_insertf128_ps(_mm256_castps128_ps256(_mm_loadu_ps(rp + 2 * (a))), \
                                        _mm_loadu_ps(rp + 2 * (b)), 1)
        __m256 y0 = TAPS((size_t)(uint32_t)i01, (size_t)(uint32_t)i45);
        __m256 y1 = TAPS((size_t)(i01 >> 32), (size_t)(i45 >> 32));
        __m256 y2 = TAPS((size_t)(uint32_t)i23, (size_t)(uint32_t)i67);
        __m256 y3 = TAPS((size_t)(i23 >> 32), (size_t)(i67 >> 32));
#undef TAPS
        __m256 t0 = _mm256_unpacklo_ps(y0, y1), t1 = _mm256_unpackhi_ps(y0, y1);
        __m256 t2 = _mm256_unpacklo_ps(y2, y3), t3 = _mm256_unpackhi_ps(y2, y3);
        __m256 q[4];   /* taps (0,0) (1,0) (0,1) (1,1) as (dx, dy) */
        q[0] = _mm256_shuffle_ps(t0, t2, _MM_SHUFFLE(1, 0, 1, 0));
        q[2] = _mm256_shuffle_ps(t0, t2, _MM_SHUFFLE(3, 2, 3, 2));
        q[1] = _mm256_shuffle_ps(t1, t3, _MM_SHUFFLE(1, 0, 1, 0));
        q[3] = _mm256_shuffle_ps(t1, t3, _MM_SHUFFLE(3, 2, 3, 2));
        __m256 top = _mm256_add_ps(q[0], _mm256_mul_ps(fx, _mm256_sub_ps(q[1], q[0])));
        __m256 bot = _mm256_add_ps(q[2], _mm256_mul_ps(fx, _mm256_sub_ps(q[3], q[2])));
        __m256 v = _mm256_add_ps(top, _mm256_mul_ps(fy, _mm256_sub_ps(bot, top)));
        acc = _mm256_add_ps(acc, v);
        _mm256_storeu_ps(col + i, _mm256_add_ps(_mm256_loadu_ps(col + i), v));
        xa = _mm256_add_epi64(xa, dx), xb = _mm256_add_epi64(xb, dx);
        ya = _mm256_add_epi64(ya, dy), yb = _mm256_add_epi64(yb, dy);
    }
    float lane[8];
    _mm256_storeu_ps(lane, acc);
    return lanes_sum(lane);
}
#endif

int radon_spatial_set_simd(radon_spatial *sp, int level)
{
    int best = 0;
#if SP_SSE2
    if (sp->w + 4 < 32768 && sp->h + 4 < 32768)
        best = __builtin_cpu_supports("avx2") ? 2 : 1;
#endif
    sp->simd = level < 0 || level > best ? best : level;
    return sp->simd;
}

/* Passes p0..p1-1 with column scratch cols; each writes only its own two
 * projections, so any split over threads gives the same bits. */
static void run_passes(const radon_spatial *sp, const float *rp, float *proj, float *cols,
                       int p0, int p1)
{
    size_t pw = (size_t)sp->w + 4;
    int ns = sp->ns, nd = sp->nd;
    for (int k = p0; k < p1; k++) {
        const sp_pass *p = sp->pass + k;
        float *prow = p->krow >= 0 ? proj + (size_t)p->krow * ns : NULL;
        memset(cols, 0, (nd + 9) * sizeof *cols);
        for (int j = p->l0; j < p->l1; j++) {
            const sp_line *l = sp->line + j;
            float *col = cols + l->i0, s;
#if SP_SSE2
            if (sp->simd == 2)
                s = line_avx2(rp, pw, l, p->ex, p->ey, col);
            else if (sp->simd == 1)
                s = line_sse2(rp, pw, l, p->ex, p->ey, col);
            else
#endif
                s = line_portable(rp, pw, l, p->ex, p->ey, col);
            if (prow)
                prow[sp->bin[l->o]] += s;
        }
        if (p->kcol >= 0) {
            float *pc = proj + (size_t)p->kcol * ns;
            for (int i = 0; i <= nd; i++)
                pc[sp->bin[i]] += cols[i];
        }
    }
}

/* The passes are claimed a few at a time by whichever thread is free,
 * not cut in fixed shares: the cores are shared with TSM's accumulation
 * and the read-ahead thread, so fixed halves left one thread waiting on
 * the other (the caller did 1.5x the helper's share at 200^2, 2
 * threads).  Each pass writes only its own two
 * projections, so who runs it does not change a bit. */
enum { SP_CLAIM = 4 };
typedef struct sp_job {
    const radon_spatial *sp;
    float *proj;
    atomic_int *next;
    float *cols;
} sp_job;

static void *job_run(void *arg)
{
    const sp_job *j = arg;
    for (int p0; (p0 = atomic_fetch_add(j->next, SP_CLAIM)) < j->sp->npass;) {
        int p1 = p0 + SP_CLAIM < j->sp->npass ? p0 + SP_CLAIM : j->sp->npass;
        run_passes(j->sp, j->sp->rp, j->proj, j->cols, p0, p1);
    }
    return NULL;
}

/* The frame into row pairs rp: pair Y holds frame rows Y - 2, Y - 1
 * (border rows stay 0). */
static void load_rows(const radon_spatial *sp, float *rp, const float *img)
{
    int w = sp->w;
    size_t pw = (size_t)w + 4;
    for (int Y = 1; Y <= sp->h + 1; Y++) {
        float *d = rp + 2 * ((size_t)Y * pw + 2);
        const float *a = Y >= 2 ? img + (size_t)(Y - 2) * w : NULL;
        const float *b = Y <= sp->h ? img + (size_t)(Y - 1) * w : NULL;
        for (int x = 0; x < w; x++)
            d[2 * x] = a ? a[x] : 0.0f, d[2 * x + 1] = b ? b[x] : 0.0f;
    }
}

float *radon_spatial_scratch_new(const radon_spatial *sp)
{
    return sp->rp ? calloc(rows_n(sp) + (size_t)sp->nd + 9, sizeof(float)) : NULL;
}

void radon_spatial_project_with(const radon_spatial *sp, float *scratch, const float *img,
                                float *proj)
{
    float *rp = scratch, *cols = scratch + rows_n(sp);
    load_rows(sp, rp, img);
    memset(proj, 0, (size_t)sp->nang * sp->ns * sizeof *proj);
    run_passes(sp, rp, proj, cols, 0, sp->npass);
}

void radon_spatial_project(radon_spatial *sp, const float *img, float *proj)
{
    int nt = sp->nthr;
    load_rows(sp, sp->rp, img);
    memset(proj, 0, (size_t)sp->nang * sp->ns * sizeof *proj);
    pthread_t th[SP_MAX_THREADS];
    sp_job job[SP_MAX_THREADS];
    atomic_int next = 0;
    for (int t = 0; t < nt; t++)
        job[t] = (sp_job){sp, proj, &next, sp->cols + (size_t)t * (sp->nd + 9)};
    int started = 0;
    for (int t = 1; t < nt; t++) {
        if (pthread_create(&th[t], NULL, job_run, &job[t]) != 0)
            break;   /* no thread: run the rest here */
        started = t;
    }
    job_run(&job[0]); /* claims whatever the threads not started leave */
    for (int t = 1; t <= started; t++)
        pthread_join(th[t], NULL);
}

radon_spatial *radon_spatial_new(int w, int h, int nangles, int ns, const radon_opts *o,
                                 const double *cs, const double *sn,
                                 const int *xlo, const int *xhi, sl_err *err)
{
    radon_spatial *sp = calloc(1, sizeof *sp);
    if (!sp) {
        sl_seterr(err, SL_ENOMEM, "radon_new: out of memory");
        return NULL;
    }
    sp->w = w, sp->h = h, sp->nang = nangles, sp->ns = ns;
    sp->cs = cs, sp->sn = sn, sp->xlo = xlo, sp->xhi = xhi;
    sp->interp = o->bp_interp;
    sp->nthr = o->threads < 1 ? 1 : o->threads > SP_MAX_THREADS ? SP_MAX_THREADS : o->threads;
    sp->up = o->bp_upsample ? o->bp_upsample : 1;
    sp->nl = 2 * ns;
    int nl = sp->nl, up = sp->up, L = nl * up;
    sp->ramp = malloc((nl / 2 + 1) * sizeof *sp->ramp);
    sp->qall = malloc((size_t)nangles * (L + 8) * sizeof *sp->qall);
    sp->l_in = fftwf_malloc(nl * sizeof(float));
    sp->l_spec = fftwf_malloc((nl / 2 + 1) * 2 * sizeof(float));
    sp->u_spec = fftwf_malloc((L / 2 + 1) * 2 * sizeof(float));
    sp->u_out = fftwf_malloc(L * sizeof(float));
    if (!sp->ramp || !sp->qall || !sp->l_in || !sp->l_spec || !sp->u_spec || !sp->u_out ||
        (o->spatial && build_projector(sp) != SL_OK)) {
        sl_seterr(err, SL_ENOMEM, "radon_new: out of memory (%dx%d, %d angles)", w, h,
                  nangles);
        goto fail_free;
    }
    unsigned flags = o->fftw_flags ? o->fftw_flags : FFTW_MEASURE;
    sp->l_r2c = fftwf_plan_dft_r2c_1d(nl, sp->l_in, (fftwf_complex *)sp->l_spec, flags);
    sp->u_c2r = fftwf_plan_dft_c2r_1d(L, (fftwf_complex *)sp->u_spec, sp->u_out, flags);
    if (!sp->l_r2c || !sp->u_c2r) {
        sl_seterr(err, SL_ENOMEM, "radon_new: FFTW planning failed");
        goto fail_free;
    }
    /* Ram-Lak kernel sampled in space (Kak & Slaney 3.61), its DFT times
     * the window, with the FBP factor pi/K and FFTW's 1/n folded in. */
    double fc = o->window_cut_cyc_px > 0 ? o->window_cut_cyc_px : 0.5;
    for (int i = 0; i < nl; i++) {
        int n = i < nl / 2 ? i : i - nl;
        sp->l_in[i] = n == 0 ? 0.25f
                    : (n & 1) ? (float)(-1.0 / (M_PI * M_PI * (double)n * n)) : 0.0f;
    }
    fftwf_execute(sp->l_r2c);
    for (int k = 0; k <= nl / 2; k++) {
        double f = (double)k / nl;
        sp->ramp[k] = (float)(sp->l_spec[2 * (k)] * radon_window_gain(o->window, f, fc) *
                              M_PI / nangles / (size_t)L * up);
    }
    return sp;
fail_free:
    radon_spatial_free(sp);
    return NULL;
}
