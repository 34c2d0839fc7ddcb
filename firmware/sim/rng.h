/* Deterministic pseudo-random numbers for the sim board (plant sensor noise and other rig effects).
 *
 * Generator: xoshiro128** (Blackman & Vigna), four 32-bit state words, period 2^128 - 1, seeded
 * from a single 32-bit seed through splitmix32, so a (seed, call sequence) pair always gives the
 * same numbers on every platform with IEEE doubles.
 * Gaussian: 128-layer ziggurat (Marsaglia & Tsang 2000) with the layer index, the sign and the
 * 24-bit magnitude taken from disjoint bits of one 32-bit draw (Doornik's fix for the correlation
 * of the original RNOR); about 98.8 % of draws take the fast path (one table compare, one
 * multiply), the rest use exp/log. rng_gauss_polar() is the slower Marsaglia polar method, kept as
 * a reference.
 */
#ifndef PLANT_RNG_H
#define PLANT_RNG_H

#include <stdint.h>

typedef struct {
    uint32_t s[4];
    double spare; /* second value of the polar method */
    int has_spare;
} rng_t;

void rng_seed(rng_t *r, uint32_t seed);

static inline uint32_t rng_rotl32_(uint32_t x, int k)
{
    return (x << k) | (x >> (32 - k));
}

/* Next 32 uniformly distributed bits (xoshiro128**). */
static inline uint32_t rng_u32(rng_t *r)
{
    uint32_t *s = r->s;
    const uint32_t result = rng_rotl32_(s[1] * 5u, 7) * 9u;
    const uint32_t t = s[1] << 9;
    s[2] ^= s[0];
    s[3] ^= s[1];
    s[1] ^= s[2];
    s[0] ^= s[3];
    s[2] ^= t;
    s[3] = rng_rotl32_(s[3], 11);
    return result;
}

/* Uniform double in the open interval (0, 1), 32-bit resolution. */
static inline double rng_uniform(rng_t *r)
{
    return ((double)rng_u32(r) + 0.5) * (1.0 / 4294967296.0);
}

/* Ziggurat tables (rng.c): k = 2^24 * x_{i-1}/x_i acceptance bounds, w = x_i / 2^24, f = exp(-x_i^2/2). */
extern const uint32_t rng_zig_k[128];
extern const double rng_zig_w[128];
extern const double rng_zig_f[128];

double rng_gauss_slow_(rng_t *r, uint32_t u);

/* Standard normal N(0, 1), ziggurat; the fast path is inline. */
static inline double rng_gauss(rng_t *r)
{
    const uint32_t u = rng_u32(r);
    const uint32_t i = u & 127u;
    const uint32_t j = u >> 8; /* 24-bit magnitude */
    if (j < rng_zig_k[i]) {
        static const double sgn[2] = { 1.0, -1.0 }; /* branch-free sign: it is a coin toss */
        return (double)j * rng_zig_w[i] * sgn[(u >> 7) & 1u];
    }
    return rng_gauss_slow_(r, u);
}

/* Standard normal by Marsaglia's polar method (reference; one log and one sqrt per pair). */
double rng_gauss_polar(rng_t *r);

#endif
