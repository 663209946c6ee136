/* rng.h: a counter-based random number generator, one independent stream per sample.
 *
 * A stream is a 64-bit key plus a counter. The n-th number of a stream is a strong 64-bit
 * mix (the SplitMix64 / Stafford "Mix13" finalizer, applied twice) of the key and n, so any
 * number can be computed without the ones before it, and streams never share state. The key
 * is hashed from (seed, a, b), e.g. (seed, pixel index, sample index) for a camera sample or
 * (seed, photon index, 0) for a photon. This is what makes images and photon maps identical
 * for any thread count and any tile order: who computes a sample does not change its numbers.
 *
 * Usage:
 *   rng g = rng_stream(seed, pixel, sample);
 *   double u = rng_uniform(&g);            // in [0, 1)
 *
 * An rng is a small value owned by its user; there is no global state.
 */
#ifndef RENDER_RNG_H
#define RENDER_RNG_H

#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

typedef struct rng {
    uint64_t key;
    uint64_t ctr;
} rng;

static inline uint64_t rng_mix64(uint64_t z) {
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
}

/* The stream for (seed, a, b). Distinct triples give unrelated streams. */
static inline rng rng_stream(uint64_t seed, uint64_t a, uint64_t b) {
    uint64_t k = rng_mix64(seed + 0x9e3779b97f4a7c15ULL);
    k = rng_mix64(k ^ (a + 0x632be59bd9b4e019ULL));
    k = rng_mix64(k ^ (b + 0x85157af5c1a3b4d3ULL));
    return (rng){k, 0};
}

static inline uint64_t rng_u64(rng *g) {
    uint64_t c = g->ctr++;
    return rng_mix64(rng_mix64(g->key ^ (c * 0x9e3779b97f4a7c15ULL)) + c);
}

/* Uniform in [0, 1): the top 53 bits, so 1.0 is never returned. */
static inline double rng_uniform(rng *g) { return (double)(rng_u64(g) >> 11) * 0x1.0p-53; }

#ifdef __cplusplus
}
#endif
#endif /* RENDER_RNG_H */
