/* stats.c: per-thread counter arrays, registered on first use and summed on demand.
 *
 * Each thread that counts gets a zeroed array of STATS_MAX counters, allocated once and kept
 * in a global list (under a mutex, taken only the first time a thread counts). Totals walk the
 * list. Names live in a fixed table; the core names are filled in at the first registration.
 */
#include "base/stats.h"

#include <pthread.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

_Thread_local uint64_t *stats__local;

#define MAX_THREAD_SLOTS 1024
static pthread_mutex_t g_lock = PTHREAD_MUTEX_INITIALIZER;
static uint64_t *g_slots[MAX_THREAD_SLOTS];
static int g_nslots;
static uint64_t g_overflow[STATS_MAX]; /* shared by threads beyond MAX_THREAD_SLOTS (racy but safe) */
static char g_names[STATS_MAX][80];
static int g_ncounters;
#define MAX_TIMERS 32
static char g_timer_names[MAX_TIMERS][80];
static double g_timers[MAX_TIMERS];
static int g_ntimers;

/* A table: one name a core counter, alike by design. */
static const char *const core_names[STAT_CORE_COUNT] = {
    [STAT_CAMERA_RAYS] = "Integrator/Camera rays",
    [STAT_INDIRECT_RAYS] = "Integrator/Indirect rays",
    [STAT_SHADOW_RAYS] = "Integrator/Shadow rays",
    [STAT_PATH_VERTICES] = "Integrator/Path vertices",
    [STAT_RR_TERMINATED] = "Integrator/Paths ended by Russian roulette",
    [STAT_MAXDEPTH] = "Integrator/Paths ended at the maximum depth",
    [STAT_SPECULAR_BOUNCES] = "Integrator/Specular bounces",
    [STAT_TIR] = "Integrator/Total internal reflections",
    [STAT_BVH_NODES] = "Accelerator/BVH nodes visited",
    [STAT_TRI_TESTS] = "Accelerator/Triangle intersection tests",
    [STAT_SPHERE_TESTS] = "Accelerator/Sphere intersection tests",
    [STAT_SAMPLES] = "Film/Samples",
};

/* Called with g_lock held. */
static void init_core_names(void) {
    if (g_ncounters) return;
    for (int i = 0; i < STAT_CORE_COUNT; i++)
        snprintf(g_names[i], sizeof g_names[i], "%s", core_names[i]);
    g_ncounters = STAT_CORE_COUNT;
}

uint64_t *stats__attach(void) {
    uint64_t *p = calloc(STATS_MAX, sizeof *p);
    pthread_mutex_lock(&g_lock);
    init_core_names();
    if (p && g_nslots < MAX_THREAD_SLOTS) {
        g_slots[g_nslots++] = p;
    } else {
        free(p);
        p = g_overflow;
    }
    pthread_mutex_unlock(&g_lock);
    stats__local = p;
    return p;
}

/* The counter named name, or -1; with add, a new one if there is none and room is left. */
static int lookup_name(const char *name, int add) {
    int id = -1;
    pthread_mutex_lock(&g_lock);
    init_core_names();
    for (int i = 0; i < g_ncounters; i++)
        if (strcmp(g_names[i], name) == 0) id = i;
    if (add && id < 0 && g_ncounters < STATS_MAX) {
        id = g_ncounters++;
        snprintf(g_names[id], sizeof g_names[id], "%s", name);
    }
    pthread_mutex_unlock(&g_lock);
    return id;
}

int stats_register(const char *name) { return lookup_name(name, 1); }

int stats_find(const char *name) { return lookup_name(name, 0); }

const char *stats_name(int id) {
    pthread_mutex_lock(&g_lock);
    init_core_names();
    const char *name = id >= 0 && id < g_ncounters ? g_names[id] : NULL;
    pthread_mutex_unlock(&g_lock);
    return name;
}

uint64_t stats_total(int id) {
    if (id < 0 || id >= STATS_MAX) return 0;
    uint64_t s = g_overflow[id];
    pthread_mutex_lock(&g_lock);
    for (int i = 0; i < g_nslots; i++) s += g_slots[i][id];
    pthread_mutex_unlock(&g_lock);
    return s;
}

uint64_t stats_trace_work(void) {
    return stats_total(STAT_BVH_NODES) + stats_total(STAT_TRI_TESTS) + stats_total(STAT_SPHERE_TESTS);
}

void stats_time_add(const char *name, double seconds) {
    pthread_mutex_lock(&g_lock);
    int i;
    for (i = 0; i < g_ntimers; i++)
        if (strcmp(g_timer_names[i], name) == 0) break;
    if (i == g_ntimers && g_ntimers < MAX_TIMERS) {
        snprintf(g_timer_names[i], sizeof g_timer_names[i], "%s", name);
        g_timers[i] = 0;
        g_ntimers++;
    }
    if (i < g_ntimers) g_timers[i] += seconds;
    pthread_mutex_unlock(&g_lock);
}

void stats_reset(void) {
    pthread_mutex_lock(&g_lock);
    for (int i = 0; i < g_nslots; i++) memset(g_slots[i], 0, STATS_MAX * sizeof(uint64_t));
    memset(g_overflow, 0, sizeof g_overflow);
    for (int i = 0; i < g_ntimers; i++) g_timers[i] = 0;
    pthread_mutex_unlock(&g_lock);
}

int stats_threads(void) {
    pthread_mutex_lock(&g_lock);
    int n = g_nslots + (g_nslots == MAX_THREAD_SLOTS); /* more share g_overflow: at least one */
    pthread_mutex_unlock(&g_lock);
    return n;
}

/* Print grouped by category, in registration order within each category. */
void stats_print(FILE *f) {
    uint64_t tot[STATS_MAX];
    int n;
    pthread_mutex_lock(&g_lock);
    init_core_names();
    n = g_ncounters;
    pthread_mutex_unlock(&g_lock);
    for (int i = 0; i < n; i++) tot[i] = stats_total(i);
    fprintf(f, "Statistics:\n");
    char done[STATS_MAX] = {0};
    for (int i = 0; i < n; i++) {
        if (done[i]) continue;
        const char *slash = strchr(g_names[i], '/');
        size_t catlen = slash ? (size_t)(slash - g_names[i]) : 0;
        fprintf(f, "  %.*s\n", (int)catlen, g_names[i]);
        for (int j = i; j < n; j++) {
            const char *s2 = strchr(g_names[j], '/');
            size_t l2 = s2 ? (size_t)(s2 - g_names[j]) : 0;
            if (done[j] || l2 != catlen || strncmp(g_names[i], g_names[j], catlen) != 0) continue;
            done[j] = 1;
            fprintf(f, "    %-48s %16llu\n", g_names[j] + (s2 ? catlen + 1 : 0),
                    (unsigned long long)tot[j]);
        }
    }
    fprintf(f, "  Threads\n    %-48s %16d\n", "Threads that counted (in this process)", stats_threads());
    if (g_ntimers) {
        fprintf(f, "  Time\n");
        for (int i = 0; i < g_ntimers; i++) {
            const char *s2 = strchr(g_timer_names[i], '/');
            fprintf(f, "    %-48s %14.3f s\n", s2 ? s2 + 1 : g_timer_names[i], g_timers[i]);
        }
    }
}

double stats_now(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}
