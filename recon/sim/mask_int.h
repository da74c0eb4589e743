/* mask_int.h - helpers shared by mask.c and mask_gen.c (not public). */
#ifndef SL_MASK_INT_H
#define SL_MASK_INT_H

/* Redundancy test of baselines a and b, with their negatives: the squared
 * distance of the closer of a-b and a+b (the caller compares with d^2). */
static inline double pair_q(double ax, double ay, double bx, double by)
{
    double mx = ax - bx, my = ay - by, px = ax + bx, py = ay + by;
    double qm = mx * mx + my * my, qp = px * px + py * py;
    return qm < qp ? qm : qp;
}

/* Baselines b = c_j - c_i (i < j) in pair order, into bx/by[n(n-1)/2]. */
static inline void baselines(const double *x, const double *y, int n,
                             double *bx, double *by)
{
    int k = 0;
    for (int i = 0; i < n; i++)
        for (int j = i + 1; j < n; j++, k++) {
            bx[k] = x[j] - x[i];
            by[k] = y[j] - y[i];
        }
}

#endif
