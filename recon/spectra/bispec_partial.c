/* bispec_partial.c - see bispec.h (bispec_partial): the accumulators as flat
 * doubles, for a sequence split over processes.  Float accumulators
 * (acc_float) travel as doubles too: the sum of the parts is taken in
 * double and rounded once on loading. */
#include <string.h>

#include "bispec_int.h"

/* The parts of the layout, in order: triples (2 nt), their squared
 * moduli (nt, SNR weights only), the power (nf) and Wirnitzer's X (2 nf,
 * photon bias only). */
static size_t nacc2(const bispec *b) { return b->acc2d || b->acc2f ? (size_t)b->nt : 0; }
static size_t nxsum(const bispec *b) { return b->xsum ? 2 * (size_t)b->nf : 0; }

static void copy_out(double *dst, const double *d, const float *f, size_t n)
{
    if (d)
        memcpy(dst, d, n * sizeof *dst);
    else
        for (size_t i = 0; i < n; i++)
            dst[i] = f[i];
}

static void copy_in(const double *src, double *d, float *f, size_t n)
{
    if (d)
        memcpy(d, src, n * sizeof *d);
    else
        for (size_t i = 0; i < n; i++)
            f[i] = (float)src[i];
}

size_t bispec_partial(bispec *b, double *buf)
{
    size_t na = 2 * (size_t)b->nt, n2 = nacc2(b), nf = (size_t)b->nf, nx = nxsum(b);
    if (!buf)
        return na + n2 + nf + nx + 3;
    bispec_flush(b); /* the batch still buffered */
    copy_out(buf, b->accd, b->accf, na);
    buf += na;
    copy_out(buf, b->acc2d, b->acc2f, n2);
    buf += n2;
    memcpy(buf, b->psum, nf * sizeof *buf);
    buf += nf;
    if (nx)
        memcpy(buf, b->xsum, nx * sizeof *buf);
    buf += nx;
    buf[0] = b->w2sum, buf[1] = b->w3sum, buf[2] = b->n;
    return na + n2 + nf + nx + 3;
}

void bispec_partial_load(bispec *b, const double *buf)
{
    size_t na = 2 * (size_t)b->nt, n2 = nacc2(b), nf = (size_t)b->nf, nx = nxsum(b);
    bispec_flush(b);
    copy_in(buf, b->accd, b->accf, na);
    buf += na;
    copy_in(buf, b->acc2d, b->acc2f, n2);
    buf += n2;
    memcpy(b->psum, buf, nf * sizeof *buf);
    buf += nf;
    if (nx)
        memcpy(b->xsum, buf, nx * sizeof *buf);
    buf += nx;
    b->w2sum = buf[0], b->w3sum = buf[1], b->n = (int)buf[2];
    b->phased = 0;
}
