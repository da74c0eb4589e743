/* rng.h - deterministic random numbers for the simulator.
 *
 * xoshiro256** seeded through splitmix64: the same seed gives the same
 * stream on every machine, so a simulation is reproducible from its seed.
 * The state is a value the caller owns (no globals); streams for separate
 * purposes come from rng_init(seed, stream) with different stream ids so
 * that, e.g., changing the photon noise does not change the phase screen.
 */
#ifndef SL_RNG_H
#define SL_RNG_H

#include <stdint.h>

typedef struct rng {
    uint64_t s[4];
    int have_spare;   /* Box-Muller produces pairs */
    double spare;
} rng;

void rng_init(rng *r, uint64_t seed, uint64_t stream);
uint64_t rng_u64(rng *r);
/* Uniform in [0, 1) with 53 random bits. */
double rng_uniform(rng *r);
/* Standard normal N(0, 1). */
double rng_normal(rng *r);
/* Poisson with mean lambda >= 0 (exact: inversion for small lambda,
 * PTRS transformed rejection for large). */
uint64_t rng_poisson(rng *r, double lambda);

#endif
