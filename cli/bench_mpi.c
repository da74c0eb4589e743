/* bench_mpi.c - see bench_mpi.h.
 *
 * Times: `recon_s` is what specklab-mpi measures from its first barrier to
 * the image written (rank 0), so mpirun's start (~0.3 s) stays out of the
 * efficiency; `wall_s` is the whole command.  One thread per rank unless
 * --threads: the ranks, not the threads, are what is measured.
 * The model: t_N = t_tail + (t_1 - t_tail) / N + ((N - 1) + ceil(log2 N))
 * S / B, with t_1 the one-rank time, t_tail what rank 0 does alone after
 * the last sums (the phases and the image; measured on 2 ranks), S the
 * bytes of sums a run reduces (specklab-mpi counts them) and B the
 * bandwidth: rank 0 receives N - 1 partial sums one after the other, and
 * the intermediate totals (direct's power spectrum) go back down a tree;
 * counting S for those too makes it an upper bound.  What each rank
 * repeats before its frames (the detector, the probe: ~32 frames) is
 * taken as parallel: small beside the frames of a sequence worth
 * splitting.
 */
#include "bench_mpi.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "cli.h"
#include "pipeline/pipeline.h"

#define NRANKS 3
static const int ranks[NRANKS] = {1, 2, 4};

typedef struct point {
    double wall_s, recon_s, bytes;
    double tail_s;        /* rank 0 alone after the last sums (0: one rank) */
} point;

/* specklab-mpi beside this program, else in PATH; NULL: none. */
static char *find_mpi_program(void)
{
    char *self = g_file_read_link("/proc/self/exe", NULL);
    char *dir = self ? g_path_get_dirname(self) : NULL;
    char *p = dir ? g_build_filename(dir, "specklab-mpi", NULL) : NULL;
    g_free(self);
    g_free(dir);
    if (p && g_file_test(p, G_FILE_TEST_IS_EXECUTABLE))
        return p;
    g_free(p);
    return g_find_program_in_path("specklab-mpi");
}

/* Run argv; its stdout (owned) or NULL with the reason on stderr. */
static char *spawn(char **argv, double *wall_s)
{
    char *out = NULL, *err = NULL;
    int status = 0;
    GError *e = NULL;
    gint64 t0 = g_get_monotonic_time();
    gboolean ok = g_spawn_sync(NULL, argv, NULL, G_SPAWN_SEARCH_PATH, NULL, NULL, &out,
                               &err, &status, &e);
    if (wall_s)
        *wall_s = (g_get_monotonic_time() - t0) * 1e-6;
    if (!ok || !g_spawn_check_wait_status(status, NULL)) {
        fprintf(stderr, "specklab bench --mpi: %s failed: %s%s\n", argv[0],
                e ? e->message : "", err ? err : "");
        g_clear_error(&e);
        g_free(out);
        out = NULL;
    }
    g_free(err);
    return out;
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* One method on n ranks, the median of repeat runs. */
static int measure(const bench_args *a, const char *prog, const char *dir,
                   const char *method, int n, point *pt)
{
    char ns[16], th[16];
    snprintf(ns, sizeof ns, "%d", n);
    snprintf(th, sizeof th, "%d", a->threads > 0 ? a->threads : 1);
    char *cube = g_build_filename(dir, "cube.fits", NULL);
    char *img = g_build_filename(dir, "image.fits", NULL);
    char *argv[32];
    int k = 0;
    argv[k++] = "mpirun";
    if (geteuid() == 0)
        argv[k++] = "--allow-run-as-root";
    /* unbound: a rank pinned to a core that something else is using
     * waits for it (bound ranks suit dedicated nodes, not this bench) */
    char *rest[] = {"--bind-to", "none", "--oversubscribe", "-n", ns, (char *)prog, "--mpi-report", "recon",
                    cube, "-m", (char *)method, "--threads", th, "-o", img,
                    "--overwrite", "-q", NULL};
    for (int i = 0; rest[i]; i++)
        argv[k++] = rest[i];
    argv[k] = NULL;
    double wall[BENCH_MAX_REPEAT], rec[BENCH_MAX_REPEAT], tail[BENCH_MAX_REPEAT];
    int rc = 0, r;
    for (r = 0; r < a->repeat && !rc; r++) {
        char *out = spawn(argv, &wall[r]);
        const char *line = out ? strstr(out, "specklab-mpi: ranks") : NULL;
        int ranks_seen = 0;
        if (!line || sscanf(line, "specklab-mpi: ranks %d, sums reduced %lf bytes, wall %lf s, "
                            "tail %lf s", &ranks_seen, &pt->bytes, &rec[r], &tail[r]) != 4)
            rc = 1;
        g_free(out);
    }
    if (!rc) {
        qsort(wall, (size_t)r, sizeof *wall, cmp_double);
        qsort(rec, (size_t)r, sizeof *rec, cmp_double);
        qsort(tail, (size_t)r, sizeof *tail, cmp_double);
        pt->wall_s = wall[r / 2];
        pt->recon_s = rec[r / 2];
        pt->tail_s = tail[r / 2];
    }
    g_free(cube);
    g_free(img);
    return rc;
}

/* one: the one-rank point; tail_s and bytes from a split run. */
static void print_model(const char *method, const point *one, double tail_s, double bytes)
{
    static const double bw[2] = {1.25e9, 12.5e9}; /* 10 GbE, 100 Gb/s */
    double par = fmax(one->recon_s - tail_s, 0);
    printf("\n%s, model for N nodes: t_N = t_tail + (t_1 - t_tail)/N + ((N-1) + log2 N) S/B;\n"
           "t_1 = %.3f s, t_tail = %.3f s (rank 0 alone after the last sums), "
           "S = %.2f MB of sums per run\n", method, one->recon_s, tail_s, bytes / 1e6);
    printf("%6s  %12s %6s  %12s %6s\n", "nodes", "10GbE t_s", "eff", "100Gb t_s", "eff");
    for (int n = 1; n <= 64; n *= 2) {
        printf("%6d", n);
        for (int b = 0; b < 2; b++) {
            double comm = n > 1 ? ((n - 1) + ceil(log2(n))) * bytes / bw[b] : 0;
            double t = n > 1 ? tail_s + par / n + comm : one->recon_s;
            printf("  %12.4f %5.0f%%", t, 100 * one->recon_s / (n * t));
        }
        printf("\n");
    }
}

/* Every method on 1, 2, 4 ranks: the table, then each one's model. */
static int run_methods(const bench_args *a, const char *prog, const char *dir,
                       char **methods)
{
    point pt[16][NRANKS];
    int nm = 0;
    printf("%-12s %5s %8s %8s %8s %8s %10s %9s\n", "method", "ranks", "wall_s", "recon_s",
           "tail_s", "speedup", "efficiency", "sums_MB");
    for (; methods[nm] && nm < 16; nm++)
        for (int i = 0; i < NRANKS; i++) {
            if (measure(a, prog, dir, methods[nm], ranks[i], &pt[nm][i]) != 0)
                return 1;
            const point *p = &pt[nm][i], *p1 = &pt[nm][0];
            double s = p1->recon_s / p->recon_s;
            printf("%-12s %5d %8.3f %8.3f %8.3f %8.2f %9.0f%% %9.2f\n", methods[nm], ranks[i],
                   p->wall_s, p->recon_s, p->tail_s, s, 100 * s / ranks[i], p->bytes / 1e6);
            fflush(stdout);
        }
    for (int m = 0; m < nm; m++)
        print_model(methods[m], &pt[m][0], pt[m][1].tail_s, pt[m][1].bytes);
    return 0;
}

/* The cube: a binary at 1e4 photons per frame, --sizes and --frames'
 * first values (default 128^2, 64 frames). */
static int simulate(const bench_args *a, const char *dir, int *size, int *frames)
{
    *size = a->sizes ? atoi(a->sizes) : 128;
    *frames = a->frames ? atoi(a->frames) : 64;
    if (*size < 16 || *frames < 4) {
        fprintf(stderr, "specklab bench --mpi: --sizes >= 16 and --frames >= 4\n");
        return 2;
    }
    char *self = g_file_read_link("/proc/self/exe", NULL);
    char *cube = g_build_filename(dir, "cube.fits", NULL);
    char ss[16], fs[16];
    snprintf(ss, sizeof ss, "%d", *size);
    snprintf(fs, sizeof fs, "%d", *frames);
    char *argv[] = {self ? self : "specklab", "sim", "--scene", "binary", "--size", ss,
                    "--frames", fs, "--photons", "1e4", "-o", cube, "--overwrite", NULL};
    char *out = spawn(argv, NULL);
    g_free(self);
    g_free(cube);
    g_free(out);
    return out ? 0 : 1;
}

int bench_mpi_run(const bench_args *a)
{
    char *prog = find_mpi_program(), *mpirun = g_find_program_in_path("mpirun");
    char *dir = a->dir ? g_strdup(a->dir) : g_dir_make_tmp("specklab-bench-mpi-XXXXXX", NULL);
    char **methods = g_strsplit(a->methods ? a->methods : "direct,tsm-fourier", ",", -1);
    int rc = 1, size = 0, frames = 0, m;
    if (!prog || !mpirun) {
        fprintf(stderr, "specklab bench --mpi: no %s (the build has no MPI: install "
                "libopenmpi-dev and openmpi-bin, then make)\n", prog ? "mpirun" : "specklab-mpi");
        goto free_all;
    }
    for (int i = 0; methods[i]; i++)
        if (pipeline_method_parse(methods[i], &m) != SL_OK) {
            fprintf(stderr, "specklab bench --mpi: unknown method '%s'\n", methods[i]);
            rc = 2;
            goto free_all;
        }
    if (!dir || g_mkdir_with_parents(dir, 0755) != 0 || (rc = simulate(a, dir, &size, &frames)))
        goto free_all;
    double load[1] = {0};
    if (getloadavg(load, 1) != 1)
        load[0] = NAN;
    printf("specklab bench --mpi: %d^2 x %d frames, 1e4 photons, %d thread(s) per rank, "
           "%ld cores, load average %.1f before, median of %d\n", size, frames,
           a->threads > 0 ? a->threads : 1, sysconf(_SC_NPROCESSORS_ONLN), load[0], a->repeat);
    rc = run_methods(a, prog, dir, methods);
free_all:
    if (dir && !a->dir) {
        char *argv[] = {"rm", "-rf", dir, NULL};
        g_spawn_sync(NULL, argv, NULL, G_SPAWN_SEARCH_PATH, NULL, NULL, NULL, NULL, NULL, NULL);
    }
    g_strfreev(methods);
    g_free(prog);
    g_free(mpirun);
    g_free(dir);
    return rc;
}
