/* stats.h: named work counters, summed over threads and printed after a render (like pbrt).
 *
 * A counter has a name "Category/What is counted", e.g. "Integrator/Shadow rays". The core
 * counters are the STAT_* enum below; any module may add its own at start-up with
 * stats_register("Photons/Caustic photons stored"), which returns an id to pass to stat_add.
 *
 * Counting is cheap and lock-free: each thread adds into its own array (found through one
 * thread-local pointer), and stats_total()/stats_print() sum the arrays of every thread that
 * ever counted. Sums of integers do not depend on the order, so the totals are the same for
 * any thread count. Read totals only when no thread is counting (after a parallel region).
 * stats_reset() zeroes everything (used between renders and by tests).
 *
 * Timers: stats_time_add("Time/Render", seconds) keeps named wall-clock times (not per
 * thread; call them from the main thread).
 *
 * stats_threads() is the number of threads that ever counted: every thread that traced a ray
 * (the BVH counts each traversal), in any phase (the plan's pilots, photon tracing, the
 * pixels). stats_print() shows it, so a run shows how many threads did its work (render
 * --threads N must give at most N).
 */
#ifndef RENDER_STATS_H
#define RENDER_STATS_H

#include <stdint.h>
#include <stdio.h>

#ifdef __cplusplus
extern "C" {
#endif

#define STATS_MAX 128

enum {
    STAT_CAMERA_RAYS,      /* Integrator/Camera rays */
    STAT_INDIRECT_RAYS,    /* Integrator/Indirect rays (bounces after the camera ray) */
    STAT_SHADOW_RAYS,      /* Integrator/Shadow rays */
    STAT_PATH_VERTICES,    /* Integrator/Path vertices */
    STAT_RR_TERMINATED,    /* Integrator/Paths ended by Russian roulette */
    STAT_MAXDEPTH,         /* Integrator/Paths ended at the maximum depth */
    STAT_SPECULAR_BOUNCES, /* Integrator/Specular bounces (mirror or refraction) */
    STAT_TIR,              /* Integrator/Total internal reflections */
    STAT_BVH_NODES,        /* Accelerator/BVH nodes visited */
    STAT_TRI_TESTS,        /* Accelerator/Triangle intersection tests */
    STAT_SPHERE_TESTS,     /* Accelerator/Sphere intersection tests */
    STAT_SAMPLES,          /* Film/Samples */
    STAT_CORE_COUNT
};

extern _Thread_local uint64_t *stats__local;
uint64_t *stats__attach(void);

/* Add n to counter id on the calling thread. */
static inline void stat_add(int id, uint64_t n) {
    uint64_t *p = stats__local;
    if (!p) p = stats__attach();
    p[id] += n;
}
static inline void stat_inc(int id) { stat_add(id, 1); }

/* Register a counter by name ("Category/What"); returns its id, the same id for the same
 * name, or -1 if the table is full. Thread-safe, but call it once, not in inner loops. */
int stats_register(const char *name);
uint64_t stats_total(int id);
/* The traversal work counted so far: BVH nodes visited plus triangle and sphere tests (the
 * unit the photon mapper's pilots weigh costs in). */
uint64_t stats_trace_work(void);
/* The id of a named counter, or -1. */
int stats_find(const char *name);
/* The name of counter id, or NULL when id is not registered. */
const char *stats_name(int id);
void stats_time_add(const char *name, double seconds);
void stats_reset(void);
/* How many threads have counted since the program started (stats_reset keeps them). */
int stats_threads(void);
/* Print every counter (zeros too, so skipped work shows as 0) and every timer. */
void stats_print(FILE *f);
/* Wall-clock seconds from a monotonic clock. */
double stats_now(void);

#ifdef __cplusplus
}
#endif
#endif /* RENDER_STATS_H */
