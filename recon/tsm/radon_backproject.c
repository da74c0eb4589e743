/* radon_backproject.c - radon_spatial_fbp (radon_spatial.h): each
 * angle's projection ramp-filtered (and upsampled) once, then the image's
 * rows, claimed a few at a time by the handle's threads, each summing the
 * filtered projections in angle order. */
#include "radon_spatial_int.h"

#include <math.h>
#include <pthread.h>
#include <stdatomic.h>
#include <string.h>

/* Keys (a = -0.5) interpolation of q at t, 32.32 fixed point. */
static inline float keys(const float *q, int64_t t)
{
    const float *p = q + (int32_t)(uint32_t)((uint64_t)t >> 32);
    float f = (float)(int32_t)((uint32_t)t >> 8) * 0x1p-24f, f2 = f * f, f3 = f2 * f;
    return p[-1] * (-0.5f * f3 + f2 - 0.5f * f) + p[0] * (1.5f * f3 - 2.5f * f2 + 1.0f) +
           p[1] * (-1.5f * f3 + 2.0f * f2 + 0.5f * f) + p[2] * (0.5f * f3 - 0.5f * f2);
}

/* row[x] += keys(q, t + x dt), x = 0..n-1: four at a time with SSE2 (the
 * four taps of a lane are one unaligned load; then a 4x4 transpose), the
 * same arithmetic as keys(), so the same bits. */
static void row_keys(float *row, const float *q, int64_t t, int64_t dt, int n)
{
    int x = 0;
#if SP_SSE2
    __m128i ta = _mm_set_epi64x(t + dt, t), tb = _mm_set_epi64x(t + 3 * dt, t + 2 * dt);
    const __m128i d4 = _mm_set1_epi64x(4 * dt);
    const __m128 scale = _mm_set1_ps(0x1p-24f);
    for (; x + 4 <= n; x += 4) {
        __m128 ta_ = _mm_castsi128_ps(ta), tb_ = _mm_castsi128_ps(tb);
        __m128i it = _mm_castps_si128(_mm_shuffle_ps(ta_, tb_, _MM_SHUFFLE(3, 1, 3, 1)));
        __m128i fi = _mm_castps_si128(_mm_shuffle_ps(ta_, tb_, _MM_SHUFFLE(2, 0, 2, 0)));
        __m128 f = _mm_mul_ps(_mm_cvtepi32_ps(_mm_srli_epi32(fi, 8)), scale);
        __m128 f2 = _mm_mul_ps(f, f), f3 = _mm_mul_ps(f2, f);
        uint64_t i01 = (uint64_t)_mm_cvtsi128_si64(it);
        uint64_t i23 = (uint64_t)_mm_cvtsi128_si64(_mm_unpackhi_epi64(it, it));
        __m128 pm = _mm_loadu_ps(q + (int32_t)(uint32_t)i01 - 1);
        __m128 p0 = _mm_loadu_ps(q + (int32_t)(uint32_t)(i01 >> 32) - 1);
        __m128 p1 = _mm_loadu_ps(q + (int32_t)(uint32_t)i23 - 1);
        __m128 p2 = _mm_loadu_ps(q + (int32_t)(uint32_t)(i23 >> 32) - 1);
        _MM_TRANSPOSE4_PS(pm, p0, p1, p2);
#define MUL(a, b) _mm_mul_ps(_mm_set1_ps(a), b)
        __m128 wm = _mm_sub_ps(_mm_add_ps(MUL(-0.5f, f3), f2), MUL(0.5f, f));
        __m128 w0 = _mm_add_ps(_mm_sub_ps(MUL(1.5f, f3), MUL(2.5f, f2)), _mm_set1_ps(1.0f));
        __m128 w1 = _mm_add_ps(_mm_add_ps(MUL(-1.5f, f3), MUL(2.0f, f2)), MUL(0.5f, f));
        __m128 w2 = _mm_sub_ps(MUL(0.5f, f3), MUL(0.5f, f2));
#undef MUL
        __m128 v = _mm_add_ps(_mm_add_ps(_mm_add_ps(_mm_mul_ps(pm, wm), _mm_mul_ps(p0, w0)),
                                         _mm_mul_ps(p1, w1)), _mm_mul_ps(p2, w2));
        _mm_storeu_ps(row + x, _mm_add_ps(_mm_loadu_ps(row + x), v));
        ta = _mm_add_epi64(ta, d4), tb = _mm_add_epi64(tb, d4);
    }
#endif
    for (; x < n; x++)
        row[x] += keys(q, t + x * dt);
}

/* Angle k's projection, ramp-filtered and upsampled, into q (L + 5
 * floats: L samples after a periodic guard of 2, and 3 after them:
 * q(s) at s < -ns/2 lives at the end of the circular buffer). */
static void filter_angle(radon_spatial *sp, const float *proj, int k, float *q)
{
    int ns = sp->ns, nl = sp->nl, up = sp->up, L = nl * up;
    memcpy(sp->l_in, proj + (size_t)k * ns, ns * sizeof(float));
    memset(sp->l_in + ns, 0, (nl - ns) * sizeof(float));
    fftwf_execute(sp->l_r2c);
    memset(sp->u_spec, 0, (L / 2 + 1) * 2 * sizeof(float));
    for (int j = 0; j <= nl / 2; j++) {
        float g = sp->ramp[j] * (up > 1 && j == nl / 2 ? 0.5f : 1.0f);
        sp->u_spec[2 * (j)] = g * sp->l_spec[2 * (j)];
        sp->u_spec[2 * (j) + 1] = g * sp->l_spec[2 * (j) + 1];
    }
    fftwf_execute(sp->u_c2r);
    memcpy(q + 2, sp->u_out, L * sizeof(float));
    q[0] = sp->u_out[L - 2], q[1] = sp->u_out[L - 1];
    q[L + 2] = sp->u_out[0], q[L + 3] = sp->u_out[1], q[L + 4] = sp->u_out[2];
}

/* Image rows [y0, y1): every angle's filtered projection added in angle
 * order, as the angle-by-angle sweep did, so each pixel gets the same
 * sum in the same order whoever runs its row. */
static void bp_rows(const radon_spatial *sp, float *img, int y0, int y1)
{
    int ns = sp->ns, up = sp->up, w = sp->w;
    size_t ld = (size_t)sp->nl * up + 8;
    for (int y = y0; y < y1; y++) {
        float *row = img + (size_t)y * w;
        memset(row, 0, (size_t)w * sizeof *row);
        for (int k = 0; k < sp->nang; k++) {
            const float *q = sp->qall + (size_t)k * ld + 2;
            double c = sp->cs[k] * up, s = sp->sn[k] * up, off = 0.5 * ns * up;
            double base = (y - sp->h / 2) * s + off - (w / 2) * c;
            if (sp->interp == RADON_INTERP_CUBIC) {
                /* t in 32.32 fixed point, within 3e-8 of base + x c */
                int x0 = sp->xlo[y];
                if (x0 <= sp->xhi[y])
                    row_keys(row + x0, q, llround(ldexp(base + x0 * c, 32)),
                             llround(ldexp(c, 32)), sp->xhi[y] - x0 + 1);
                continue;
            }
            for (int x = sp->xlo[y]; x <= sp->xhi[y]; x++) {
                double t = base + x * c;
                int i = (int)floor(t);
                float f = (float)(t - i);
                row[x] += q[i] + f * (q[i + 1] - q[i]);
            }
        }
    }
}

/* The back projection's rows are claimed BP_ROWS at a time by whichever
 * thread is free (the filtering, ~2 % of it, stays on the caller). */
enum { BP_ROWS = 4 };
typedef struct bp_job {
    const radon_spatial *sp;
    float *img;
    atomic_int *next;
} bp_job;

static void *bp_run(void *arg)
{
    const bp_job *j = arg;
    for (int y0; (y0 = atomic_fetch_add(j->next, BP_ROWS)) < j->sp->h;)
        bp_rows(j->sp, j->img, y0, y0 + BP_ROWS < j->sp->h ? y0 + BP_ROWS : j->sp->h);
    return NULL;
}

void radon_spatial_fbp(radon_spatial *sp, const float *proj, float *img)
{
    size_t ld = (size_t)sp->nl * sp->up + 8;
    for (int k = 0; k < sp->nang; k++)
        filter_angle(sp, proj, k, sp->qall + (size_t)k * ld);
    pthread_t th[SP_MAX_THREADS];
    atomic_int next = 0;
    bp_job job = {sp, img, &next};
    int started = 0;
    for (int t = 1; t < sp->nthr; t++) {
        if (pthread_create(&th[t], NULL, bp_run, &job) != 0)
            break;   /* no thread: run the rest here */
        started = t;
    }
    bp_run(&job);
    for (int t = 1; t <= started; t++)
        pthread_join(th[t], NULL);
}
