/* render_mpi.c: main() of render-mpi, the distributed renderer (dist.h says how it works).
 *
 *   mpirun -np N render-mpi SCENE.json [render's options] [--pm distributed=replicated]
 *
 * It starts MPI, takes the options that only a distributed render has, and runs render's own
 * program (render_main, render/app/app.h) on every rank, with the hooks of a distributed
 * render: dist.c's image loops and pass agreement, and passes refused when partitioned. What it changes in the
 * arguments, per rank (added ones go first, so that a last option missing its value gets
 * render's own message):
 *   - --threads: when not given, the cores of the node divided among the ranks on it (OpenMP
 *     would otherwise start all cores' worth of threads in every rank);
 *   - ranks > 0 get --quiet and lose --save-photons (rank 0 saves the maps once).
 * The tools (--compare, --tonemap, --dump-scene, --help-settings) run on rank 0 alone, as
 * render runs them; --help and --help-settings add what only render-mpi has.
 * Checkpoints (--checkpoint, --resume, --snapshot-every) are render's: rank 0 writes them
 * (checkpoint.h, ckpt_set_distributed; dist.h). A resumed render takes the distribution of
 * its checkpoint when none is given: a partitioned checkpoint says so in its settings text.
 */
#include <mpi.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "app/app.h"
#include "run/checkpoint.h"
#include "dist.h"

static void usage_mpi(void) {
    printf("\nrender-mpi (the same options, run under mpirun):\n"
           "  mpirun -np N render-mpi SCENE.json [options] [--pm distributed=MODE]\n"
           "  --pm distributed=replicated   every rank holds all photons (the default): the\n"
           "                    image is bit-identical to render's\n"
           "  --pm distributed=partitioned  every rank keeps 1/N of the photon maps; estimates\n"
           "                    combine the ranks' parts (docs/MPI.md: accuracy, traffic);\n"
           "                    a command-line setting only (not in the scene's photon_mapping)\n"
           "  --threads N       OpenMP threads per rank (default: the node's cores divided\n"
           "                    among its ranks)\n"
           "  --checkpoint, --checkpoint-every, --resume, --snapshot-every: as in render; rank 0\n"
           "                    writes the files, and a replicated render's checkpoint is\n"
           "                    render's (either resumes it, at any -np); a partitioned one\n"
           "                    resumes at the same -np only\n"
           "  --time, --passes, --pass-spp: as in render, in the replicated mode (the image\n"
           "                    is render's, bit for bit); refused (exit 2) with\n"
           "                    --pm distributed=partitioned\n"
           "  --save-photons DIR  written by rank 0 alone; refused (exit 2) with\n"
           "                    --pm distributed=partitioned (no rank holds the whole maps)\n"
           "  --load-photons DIR  read by every rank (DIR on storage every rank can read)\n"
           "  -o, --hdr         written by rank 0 alone, once, at the end; the directory\n"
           "                    must exist on every rank's node\n"
           "  --compare, --tonemap, --dump-scene, --help-settings: run by rank 0 alone\n"
           "  exit status: as render's; a rank that fails stops every rank, and rank 0 names\n"
           "                    it (\"rank K of N failed ...\"), nothing written\n");
}

/* --help-settings adds the one setting that render-mpi alone has, in the same form. */
static void settings_mpi(int markdown) {
    if (markdown)
        printf("| `distributed` | string | \"replicated\" | replicated, partitioned | render-mpi "
               "only, and only as --pm distributed=MODE: every rank holds the whole photon maps "
               "(replicated) or 1/N of them (partitioned) |\n");
    else
        printf("  distributed          string, default \"replicated\", replicated, partitioned\n"
               "                       render-mpi only, and only as --pm distributed=MODE:\n"
               "                       every rank holds the whole photon maps (replicated) or\n"
               "                       1/N of them (partitioned)\n");
}

int main(int argc, char **argv) {
    int provided;
    if (MPI_Init_thread(&argc, &argv, MPI_THREAD_FUNNELED, &provided) != MPI_SUCCESS) {
        fprintf(stderr, "render-mpi: MPI_Init failed\n");
        return 1;
    }
    int rank;
    MPI_Comm_rank(MPI_COMM_WORLD, &rank);
    char msg[512] = "";
    int mode = DIST_REPLICATED, has_threads = 0, help = 0, has_save = 0, has_mode = 0;
    const char *resume = NULL;
    char **av = calloc((size_t)argc + 4, sizeof *av);
    int ac = 0;
    if (!av) {
        fprintf(stderr, "render-mpi: out of memory\n");
        MPI_Abort(MPI_COMM_WORLD, 1);
    }
    for (int i = 0; i < argc; i++) {
        const char *a = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
        if (i > 0 && strcmp(a, "--pm") == 0 && v && strncmp(v, "distributed=", 12) == 0) {
            has_mode = 1;
            if (strcmp(v + 12, "replicated") == 0) {
                mode = DIST_REPLICATED;
            } else if (strcmp(v + 12, "partitioned") == 0) {
                mode = DIST_PARTITIONED;
            } else {
                snprintf(msg, sizeof msg, "render-mpi: --pm distributed: expected replicated or "
                         "partitioned, got '%s'", v + 12);
            }
            i++;
            continue;
        }
        if (i > 0 && strcmp(a, "--resume") == 0 && v) resume = v;
        if (i > 0 && strcmp(a, "--save-photons") == 0) has_save = 1;
        if (i > 0 && rank > 0 && strcmp(a, "--save-photons") == 0 && v) {
            i++;
            continue;
        }
        if (strcmp(a, "--threads") == 0) has_threads = 1;
        if (strcmp(a, "--help") == 0 || strcmp(a, "-h") == 0) help = 1;
        av[ac++] = argv[i];
    }
    if (!msg[0] && has_save && mode == DIST_PARTITIONED)
        snprintf(msg, sizeof msg, "render-mpi: --save-photons is not available with --pm "
                 "distributed=partitioned (no rank holds the whole maps; save them with the "
                 "replicated mode or render)");
    /* A resumed render without --pm distributed=...: its checkpoint's (main.c reads the file
     * again, and says why when it cannot). */
    if (!msg[0] && resume && !has_mode) {
        ckpt_info *ci = malloc(sizeof *ci);
        char cerr[64];
        if (ci && ckpt_read(resume, ci, NULL, cerr, sizeof cerr) == 0 &&
            strstr(ci->settings, "; distributed partitioned over "))
            mode = DIST_PARTITIONED;
        free(ci);
    }
    dist_init(mode);
    /* Ranks sharing this node share its cores. Every rank asks (a collective call) before
     * anything else, whatever its command: ranks given different commands, or one with a bad
     * option, must meet in the ranks' agreement (ranks.c). */
    MPI_Comm node;
    int local = 1;
    if (MPI_Comm_split_type(MPI_COMM_WORLD, MPI_COMM_TYPE_SHARED, 0, MPI_INFO_NULL, &node) ==
        MPI_SUCCESS) {
        MPI_Comm_size(node, &local);
        MPI_Comm_free(&node);
    }
    if (msg[0]) dist_fail_early(2, msg);
    static char threads_arg[24];
    int settings = argc == 2 && (strcmp(argv[1], "--help-settings") == 0 ||
                                 strcmp(argv[1], "--help-settings=markdown") == 0);
    int tool = settings || (argc > 1 && (strcmp(argv[1], "--compare") == 0 ||
                                         strcmp(argv[1], "--tonemap") == 0 ||
                                         strcmp(argv[1], "--dump-scene") == 0));
    /* The added arguments go right after the program's name. */
    int at = ac > 0 ? 1 : 0;
    char *added[3];
    int nadd = 0;
    if (!has_threads && !tool && !help) {
        long cores = sysconf(_SC_NPROCESSORS_ONLN);
        long t = cores > 0 ? cores / local : 1;
        snprintf(threads_arg, sizeof threads_arg, "%ld", t > 0 ? t : 1);
        added[nadd++] = "--threads";
        added[nadd++] = threads_arg;
    }
    if (rank > 0 && !tool) added[nadd++] = "--quiet";
    memmove(av + at + nadd, av + at, (size_t)(ac - at) * sizeof *av);
    for (int k = 0; k < nadd; k++) av[at + k] = added[k];
    ac += nadd;
    av[ac] = NULL;
    /* render's program with dist.c's image loops (app/app.h); passes only when replicated. */
    render_hooks hooks = {dist_render_image_ctl, dist_pass_image, dist_pass_agree, dist_pass_share, dist_passes_end,
                          NULL};
    if (dist_partitioned()) /* each pass would partition fresh maps */
        hooks.no_passes = "render-mpi: rendering in passes (--time, --passes, --only-pass or the "
                          "scene's render.time) is not available with --pm distributed=partitioned (each "
                          "pass would partition fresh maps); use the replicated mode, or --spp for one "
                          "pass of fixed work";
    /* A tool's output is rank 0's (the others' stdout is discarded; two ranks would write
     * --tonemap's file twice). */
    int rc = tool && rank > 0 ? 0 : render_main(ac, av, &hooks);
    free(av);
    if (help && rank == 0) usage_mpi();
    if (settings && rank == 0 && rc == 0) settings_mpi(argv[1][15] == '=');
    fflush(stdout);
    return dist_finish(rc);
}
