/* bispec_lanes.c - the triple kernel's arithmetic, once per instruction
 * set: for one target u and a run of its stored triples, sum
 * I(u1) I(u2) conj I(u) over the batch's frames and add the sums to the
 * accumulators.  bispec_kernel.c walks the targets and calls a run.
 *
 * Arithmetic, per frame (lane), each step rounded once (fma: one
 * rounding of a b + c):
 *   ab_r = fma(a_r, b_r, -(a_i b_i)),   ab_i = fma(a_r, b_i, a_i b_r)
 *   first moment only:
 *     s_r = fma(ab_i, c_i, fma(ab_r, c_r, s_r))
 *     s_i = fma(-ab_r, c_i, fma(ab_i, c_r, s_i))
 *   with the second moment (x = ab conj c is needed per frame):
 *     x_r = fma(ab_r, c_r, ab_i c_i),   x_i = fma(ab_i, c_r, -(ab_r c_i))
 *     s_r += x_r,  s_i += x_i,  s_2 = fma(x_i, x_i, fma(x_r, x_r, s_2))
 * over the batch's vectors of 16 lanes in order, then across the lanes by
 * one tree: lane i + lane i + 8, then j + j + 4, then (0 + 2) + (1 + 3).
 * The sum goes to the accumulator in its own precision.
 *
 * Paths.  AVX-512 (one register per vector), AVX2 with FMA (two), and a
 * portable one in plain C with fmaf, which C defines as singly rounded:
 * the same operations, so every path gives the same bits (the portable
 * one is slow; it serves CPUs without AVX2 and FMA, and the test that
 * compares the paths).  bispec_opts.simd picks one; 0 takes the best
 * the CPU has.
 *
 * Cost.  Per triple and 16 frames: 4 loads of legs (the target's leg is
 * re-read from L1) and 8 vector operations, 10 with the second moment;
 * per triple ~14 more for the tree and the accumulator.  Fused products
 * took a quarter of the operations of separate ones, and the tree in
 * registers half of one stored to the stack.  The AVX-512 path sums four
 * triples of a run at once, each with its own operations in its own
 * order (the same bits): one triple alone waits on its sums' chain of
 * fused operations, 2 x 4 cycles per vector.
 */
#include "bispec_int.h"

#include <math.h>
#include <string.h>

#if defined(__x86_64__) && defined(__GNUC__)
#define LANES_X86 1
#include <immintrin.h>
#endif

/* A run function from a triple body TRI(b, pa, pb, pc, t, nch, K) and
 * a four-triple one TRI4: the triples of target j from t on while below
 * tend and in the disk segment (entries below kend).  No prefetching:
 * bispec_kernel.c's order keeps a segment's legs in L1, where asking for
 * the next triples' legs would only take load slots. */
#define LEG1(t_) (fb + (size_t)lut[-b->doff[b->tk[t_]]] * 2 * K)
#define LEG2(t_) (fb + (size_t)b->dleg[b->tk[t_]] * 2 * K)
#define RUN(NAME, ATTR, TRI, TRI4)                                           \
    ATTR static int64_t NAME(const bispec *b, int j, int64_t t, int64_t tend, \
                             int kend, int nch)                              \
    {                                                                        \
        const size_t K = (size_t)b->kb;                                      \
        const float *fb = b->fb, *pc = fb + (size_t)j * 2 * K;               \
        const int32_t *lut = b->lut + b->ubase[j];                           \
        for (; t + 3 < tend && b->tk[t + 3] < kend; t += 4) {                \
            const float *pa[4] = {LEG1(t), LEG1(t + 1), LEG1(t + 2), LEG1(t + 3)}; \
            const float *pb[4] = {LEG2(t), LEG2(t + 1), LEG2(t + 2), LEG2(t + 3)}; \
            TRI4(b, pa, pb, pc, t, nch, K);                                  \
        }                                                                    \
        for (; t < tend && b->tk[t] < kend; t++)                             \
            TRI(b, LEG1(t), LEG2(t), pc, t, nch, K);                         \
        return t;                                                            \
    }

/* The sums re, im (and s2) of triple t into the accumulators. */
#define STORE(ACC, SNR, re, im, s2) STORE_AT(ACC, SNR, t, re, im, s2)
#define STORE_AT(ACC, SNR, tt, re, im, s2)                                   \
    do {                                                                     \
        int64_t t_ = (tt);                                                   \
        ACC *acc_ = (ACC *)(sizeof(ACC) == sizeof(double) ? (void *)b->accd  \
                                                          : (void *)b->accf); \
        acc_[2 * t_] += (ACC)(re);                                           \
        acc_[2 * t_ + 1] += (ACC)(im);                                        \
        if (SNR) {                                                           \
            ACC *a2_ = (ACC *)(sizeof(ACC) == sizeof(double)                 \
                                   ? (void *)b->acc2d : (void *)b->acc2f);   \
            a2_[t_] += (ACC)(s2);                                            \
        }                                                                    \
    } while (0)

/* Four triples one after another (the paths without an interleaved
 * body). */
#define TRI4_OF(NAME, ATTR, TRI)                                             \
    ATTR static inline void NAME(const bispec *b, const float *const *pa,   \
                                 const float *const *pb, const float *pc,   \
                                 int64_t t, int nch, size_t K)               \
    {                                                                        \
        for (int q = 0; q < 4; q++)                                          \
            TRI(b, pa[q], pb[q], pc, t + q, nch, K);                         \
    }

/* ---- portable ---------------------------------------------------- */

/* The tree over 16 lanes. */
static float tree16(const float *s)
{
    float a[8], q[4];
    for (int i = 0; i < 8; i++)
        a[i] = s[i] + s[i + 8];
    for (int i = 0; i < 4; i++)
        q[i] = a[i] + a[i + 4];
    return (q[0] + q[2]) + (q[1] + q[3]);
}

#define TRI_PORTABLE(NAME, ACC, SNR)                                         \
    static inline void NAME(const bispec *b, const float *pa, const float *pb, \
                            const float *pc, int64_t t, int nch, size_t K)   \
    {                                                                        \
        float sr[16] = {0}, si[16] = {0}, s2[16] = {0};                      \
        for (size_t l = 0; l < (size_t)nch * 16; l++) {                      \
            float ar = pa[l], ai = pa[K + l], br = pb[l], bi = pb[K + l];    \
            float cr = pc[l], ci = pc[K + l];                                \
            float abr = fmaf(ar, br, -(ai * bi));                            \
            float abi = fmaf(ar, bi, ai * br);                               \
            if (!(SNR)) {                                                    \
                sr[l % 16] = fmaf(abi, ci, fmaf(abr, cr, sr[l % 16]));       \
                si[l % 16] = fmaf(-abr, ci, fmaf(abi, cr, si[l % 16]));      \
            } else {                                                         \
                float xr = fmaf(abr, cr, abi * ci);                          \
                float xi = fmaf(abi, cr, -(abr * ci));                       \
                sr[l % 16] += xr;                                            \
                si[l % 16] += xi;                                            \
                s2[l % 16] = fmaf(xi, xi, fmaf(xr, xr, s2[l % 16]));         \
            }                                                                \
        }                                                                    \
        STORE(ACC, SNR, tree16(sr), tree16(si), tree16(s2));                 \
    }
TRI_PORTABLE(tri_p_d, double, 0)
TRI_PORTABLE(tri_p_ds, double, 1)
TRI_PORTABLE(tri_p_f, float, 0)
TRI_PORTABLE(tri_p_fs, float, 1)
TRI4_OF(tri4_p_d, , tri_p_d)
TRI4_OF(tri4_p_ds, , tri_p_ds)
TRI4_OF(tri4_p_f, , tri_p_f)
TRI4_OF(tri4_p_fs, , tri_p_fs)
RUN(run_p_d, , tri_p_d, tri4_p_d)
RUN(run_p_ds, , tri_p_ds, tri4_p_ds)
RUN(run_p_f, , tri_p_f, tri4_p_f)
RUN(run_p_fs, , tri_p_fs, tri4_p_fs)

#ifdef LANES_X86
/* ---- x86: the tree's last two steps on [x0..3] and [y0..3] ---------- */

/* [sum x, sum y, ...] from the 4-lane partial sums x and y. */
__attribute__((target("sse3"))) static inline __m128 tree4x2(__m128 x, __m128 y)
{
    __m128 w = _mm_add_ps(_mm_movelh_ps(x, y), _mm_movehl_ps(y, x));
    return _mm_hadd_ps(w, w); /* (x0 + x2) + (x1 + x3), same for y */
}

/* ---- AVX-512 ----------------------------------------------------- */

__attribute__((target("avx512f"))) static inline __m128 tree512(__m512 a, __m512 c)
{
    __m512 s = _mm512_add_ps(_mm512_shuffle_f32x4(a, c, _MM_SHUFFLE(1, 0, 1, 0)),
                             _mm512_shuffle_f32x4(a, c, _MM_SHUFFLE(3, 2, 3, 2)));
    s = _mm512_add_ps(s, _mm512_shuffle_f32x4(s, s, _MM_SHUFFLE(2, 3, 0, 1)));
    return tree4x2(_mm512_castps512_ps128(s), _mm512_extractf32x4_ps(s, 2));
}

#define ZATTR __attribute__((target("avx512f")))
#define TRI_AVX512(NAME, ACC, SNR)                                           \
    ZATTR static inline void NAME(const bispec *b, const float *pa, const float *pb, \
                                  const float *pc, int64_t t, int nch, size_t K) \
    {                                                                        \
        __m512 sr = _mm512_setzero_ps(), si = sr, s2 = sr;                   \
        for (size_t l = 0; l < (size_t)nch * 16; l += 16) {                  \
            __m512 ar = _mm512_loadu_ps(pa + l), ai = _mm512_loadu_ps(pa + K + l); \
            __m512 br = _mm512_loadu_ps(pb + l), bi = _mm512_loadu_ps(pb + K + l); \
            __m512 cr = _mm512_loadu_ps(pc + l), ci = _mm512_loadu_ps(pc + K + l); \
            __m512 abr = _mm512_fmsub_ps(ar, br, _mm512_mul_ps(ai, bi));     \
            __m512 abi = _mm512_fmadd_ps(ar, bi, _mm512_mul_ps(ai, br));     \
            if (!(SNR)) {                                                    \
                sr = _mm512_fmadd_ps(abi, ci, _mm512_fmadd_ps(abr, cr, sr)); \
                si = _mm512_fnmadd_ps(abr, ci, _mm512_fmadd_ps(abi, cr, si)); \
            } else {                                                         \
                __m512 xr = _mm512_fmadd_ps(abr, cr, _mm512_mul_ps(abi, ci)); \
                __m512 xi = _mm512_fmsub_ps(abi, cr, _mm512_mul_ps(abr, ci)); \
                sr = _mm512_add_ps(sr, xr);                                  \
                si = _mm512_add_ps(si, xi);                                  \
                s2 = _mm512_fmadd_ps(xi, xi, _mm512_fmadd_ps(xr, xr, s2));   \
            }                                                                \
        }                                                                    \
        float h[4], h2[4] = {0};                                             \
        _mm_storeu_ps(h, tree512(sr, si));                                   \
        if (SNR)                                                             \
            _mm_storeu_ps(h2, tree512(s2, s2));                              \
        STORE(ACC, SNR, h[0], h[1], h2[0]);                                  \
    }
TRI_AVX512(tri_z_d, double, 0)
TRI_AVX512(tri_z_ds, double, 1)
TRI_AVX512(tri_z_f, float, 0)
TRI_AVX512(tri_z_fs, float, 1)
/* Four triples of one target at once: the same operations per triple
 * (so the same bits), but four independent chains of sums.  One triple
 * alone waits on its sums' fused chain, 2 x 4 cycles per vector; the
 * target's leg is loaded once for the four. */
#define TRI4_AVX512(NAME, ACC, SNR)                                          \
    ZATTR static inline void NAME(const bispec *b, const float *const *pa,  \
                                  const float *const *pb, const float *pc,  \
                                  int64_t t, int nch, size_t K)              \
    {                                                                        \
        __m512 sr[4], si[4], s2[4];                                          \
        for (int q = 0; q < 4; q++)                                          \
            sr[q] = si[q] = s2[q] = _mm512_setzero_ps();                     \
        for (size_t l = 0; l < (size_t)nch * 16; l += 16) {                  \
            __m512 cr = _mm512_loadu_ps(pc + l), ci = _mm512_loadu_ps(pc + K + l); \
            _Pragma("GCC unroll 4") for (int q = 0; q < 4; q++) {            \
                __m512 ar = _mm512_loadu_ps(pa[q] + l);                      \
                __m512 ai = _mm512_loadu_ps(pa[q] + K + l);                  \
                __m512 br = _mm512_loadu_ps(pb[q] + l);                      \
                __m512 bi = _mm512_loadu_ps(pb[q] + K + l);                  \
                __m512 abr = _mm512_fmsub_ps(ar, br, _mm512_mul_ps(ai, bi)); \
                __m512 abi = _mm512_fmadd_ps(ar, bi, _mm512_mul_ps(ai, br)); \
                if (!(SNR)) {                                                \
                    sr[q] = _mm512_fmadd_ps(abi, ci, _mm512_fmadd_ps(abr, cr, sr[q])); \
                    si[q] = _mm512_fnmadd_ps(abr, ci, _mm512_fmadd_ps(abi, cr, si[q])); \
                } else {                                                     \
                    __m512 xr = _mm512_fmadd_ps(abr, cr, _mm512_mul_ps(abi, ci)); \
                    __m512 xi = _mm512_fmsub_ps(abi, cr, _mm512_mul_ps(abr, ci)); \
                    sr[q] = _mm512_add_ps(sr[q], xr);                        \
                    si[q] = _mm512_add_ps(si[q], xi);                        \
                    s2[q] = _mm512_fmadd_ps(xi, xi, _mm512_fmadd_ps(xr, xr, s2[q])); \
                }                                                            \
            }                                                                \
        }                                                                    \
        _Pragma("GCC unroll 4") for (int q = 0; q < 4; q++) {                \
            float h[4], h2[4] = {0};                                         \
            _mm_storeu_ps(h, tree512(sr[q], si[q]));                         \
            if (SNR)                                                         \
                _mm_storeu_ps(h2, tree512(s2[q], s2[q]));                    \
            STORE_AT(ACC, SNR, t + q, h[0], h[1], h2[0]);                    \
        }                                                                    \
    }
TRI4_AVX512(tri4_z_d, double, 0)
TRI4_AVX512(tri4_z_ds, double, 1)
TRI4_AVX512(tri4_z_f, float, 0)
TRI4_AVX512(tri4_z_fs, float, 1)
RUN(run_z_d, ZATTR, tri_z_d, tri4_z_d)
RUN(run_z_ds, ZATTR, tri_z_ds, tri4_z_ds)
RUN(run_z_f, ZATTR, tri_z_f, tri4_z_f)
RUN(run_z_fs, ZATTR, tri_z_fs, tri4_z_fs)

/* ---- AVX2 + FMA: a 16-lane vector is two 8-lane halves, lo and hi -- */

__attribute__((target("avx2,fma"))) static inline __m128 tree256(__m256 alo, __m256 ahi,
                                                                  __m256 clo, __m256 chi)
{
    __m256 a = _mm256_add_ps(alo, ahi), c = _mm256_add_ps(clo, chi);
    return tree4x2(_mm_add_ps(_mm256_castps256_ps128(a), _mm256_extractf128_ps(a, 1)),
                   _mm_add_ps(_mm256_castps256_ps128(c), _mm256_extractf128_ps(c, 1)));
}

/* One half (offset o: 0 or 8) of one vector l of the batch. */
#define HALF256(SNR, o, sr, si, s2)                                          \
    do {                                                                     \
        __m256 ar = _mm256_loadu_ps(pa + l + o), ai = _mm256_loadu_ps(pa + K + l + o); \
        __m256 br = _mm256_loadu_ps(pb + l + o), bi = _mm256_loadu_ps(pb + K + l + o); \
        __m256 cr = _mm256_loadu_ps(pc + l + o), ci = _mm256_loadu_ps(pc + K + l + o); \
        __m256 abr = _mm256_fmsub_ps(ar, br, _mm256_mul_ps(ai, bi));         \
        __m256 abi = _mm256_fmadd_ps(ar, bi, _mm256_mul_ps(ai, br));         \
        if (!(SNR)) {                                                        \
            sr = _mm256_fmadd_ps(abi, ci, _mm256_fmadd_ps(abr, cr, sr));     \
            si = _mm256_fnmadd_ps(abr, ci, _mm256_fmadd_ps(abi, cr, si));    \
        } else {                                                             \
            __m256 xr = _mm256_fmadd_ps(abr, cr, _mm256_mul_ps(abi, ci));    \
            __m256 xi = _mm256_fmsub_ps(abi, cr, _mm256_mul_ps(abr, ci));    \
            sr = _mm256_add_ps(sr, xr);                                      \
            si = _mm256_add_ps(si, xi);                                      \
            s2 = _mm256_fmadd_ps(xi, xi, _mm256_fmadd_ps(xr, xr, s2));       \
        }                                                                    \
    } while (0)

#define YATTR __attribute__((target("avx2,fma")))
#define TRI_AVX2(NAME, ACC, SNR)                                             \
    YATTR static inline void NAME(const bispec *b, const float *pa, const float *pb, \
                                  const float *pc, int64_t t, int nch, size_t K) \
    {                                                                        \
        __m256 z = _mm256_setzero_ps();                                      \
        __m256 srl = z, sil = z, s2l = z, srh = z, sih = z, s2h = z;         \
        for (size_t l = 0; l < (size_t)nch * 16; l += 16) {                  \
            HALF256(SNR, 0, srl, sil, s2l);                                  \
            HALF256(SNR, 8, srh, sih, s2h);                                  \
        }                                                                    \
        float h[4], h2[4] = {0};                                             \
        _mm_storeu_ps(h, tree256(srl, srh, sil, sih));                       \
        if (SNR)                                                             \
            _mm_storeu_ps(h2, tree256(s2l, s2h, s2l, s2h));                  \
        STORE(ACC, SNR, h[0], h[1], h2[0]);                                  \
    }
TRI_AVX2(tri_y_d, double, 0)
TRI_AVX2(tri_y_ds, double, 1)
TRI_AVX2(tri_y_f, float, 0)
TRI_AVX2(tri_y_fs, float, 1)
TRI4_OF(tri4_y_d, YATTR, tri_y_d)
TRI4_OF(tri4_y_ds, YATTR, tri_y_ds)
TRI4_OF(tri4_y_f, YATTR, tri_y_f)
TRI4_OF(tri4_y_fs, YATTR, tri_y_fs)
RUN(run_y_d, YATTR, tri_y_d, tri4_y_d)
RUN(run_y_ds, YATTR, tri_y_ds, tri4_y_ds)
RUN(run_y_f, YATTR, tri_y_f, tri4_y_f)
RUN(run_y_fs, YATTR, tri_y_fs, tri4_y_fs)
#endif /* LANES_X86 */

int bispec_simd_best(void)
{
#ifdef LANES_X86
    __builtin_cpu_init();
    if (__builtin_cpu_supports("avx512f"))
        return BISPEC_SIMD_AVX512;
    if (__builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma"))
        return BISPEC_SIMD_AVX2;
#endif
    return BISPEC_SIMD_PORTABLE;
}

int bispec_simd_has(int simd)
{
    int best = bispec_simd_best();
    return simd == BISPEC_SIMD_AUTO || simd == BISPEC_SIMD_PORTABLE ||
           (simd == BISPEC_SIMD_AVX2 && best >= BISPEC_SIMD_AVX2) ||
           (simd == BISPEC_SIMD_AVX512 && best == BISPEC_SIMD_AVX512);
}

const char *bispec_simd_name(int simd)
{
    static const char *const name[] = {"auto", "portable", "avx2", "avx512"};
    return simd >= 0 && simd <= BISPEC_SIMD_AVX512 ? name[simd] : "?";
}

bispec_run_fn bispec_lanes_run(int simd, int acc_float, int snr)
{
    static const bispec_run_fn portable[2][2] = {{run_p_d, run_p_ds}, {run_p_f, run_p_fs}};
#ifdef LANES_X86
    static const bispec_run_fn avx2[2][2] = {{run_y_d, run_y_ds}, {run_y_f, run_y_fs}};
    static const bispec_run_fn avx512[2][2] = {{run_z_d, run_z_ds}, {run_z_f, run_z_fs}};
    if (simd == BISPEC_SIMD_AVX512)
        return avx512[!!acc_float][!!snr];
    if (simd == BISPEC_SIMD_AVX2)
        return avx2[!!acc_float][!!snr];
#endif
    (void)simd;
    return portable[!!acc_float][!!snr];
}
