/* reprocess.c - see reprocess.h. */
#include "reprocess.h"

#include <errno.h>
#include <fcntl.h>
#include <mpi.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "catalog.h"
#include "cli.h"
#include "io/cube.h"

enum { TAG_RESULT = 1, TAG_JOB = 2, TAG_STOP = 3 };

/* One run to reconstruct: what rank 0 sends. */
typedef struct rjob {
    int idx;                          /* in rank 0's list; -1: none */
    char uuid[CATALOG_UUID_LEN + 1];
    char cube[1024];
} rjob;

/* What a rank sends back: the image written and the row's numbers. */
typedef struct rresult {
    int idx;                          /* -1: ready for a first job */
    int ok, ran, nframes, width, height, found;
    int64_t started_ms;
    double elapsed_s, sep_px, sep_err_px, pa_deg, pa_err_deg, dm_mag, dm_err_mag;
    double plate_scale_arcsec;
    char fits[1100];
    char msg[sizeof(sl_err){0}.msg];
} rresult;

typedef struct rargs {
    char *catalog, *method, *since, *out_dir;
    int method_id;
    int64_t since_ms;
} rargs;

/* outdir/UUID-METHOD.fits, or -2, -3...: never over an earlier image. */
static int claim_output(const char *dir, const rjob *j, const char *method,
                        char *path, size_t n)
{
    for (int k = 1; k < 1000; k++) {
        if (k == 1)
            snprintf(path, n, "%s/%s-%s.fits", dir, j->uuid, method);
        else
            snprintf(path, n, "%s/%s-%s-%d.fits", dir, j->uuid, method, k);
        int fd = open(path, O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0644);
        if (fd >= 0)
            return close(fd), SL_OK;
        if (errno != EEXIST)
            return SL_EIO;
    }
    return SL_EIO;
}

/* Reconstruct one run as specklabd's worker does (auto's skips, the
 * binary measured and judged) and write its image. */
static void reconstruct(const rargs *a, const rjob *j, rresult *r)
{
    memset(r, 0, sizeof *r);
    r->idx = j->idx;
    r->started_ms = catalog_now_ms();
    pipeline_opts o;
    pipeline_opts_defaults(&o);
    o.method = a->method_id;
    o.closure_binary = 1;
    pipeline_result res;
    sl_err e = {0};
    const char *cube = j->cube;
    if (pipeline_run(&cube, 1, &o, &res, &e) != SL_OK) {
        snprintf(r->msg, sizeof r->msg, "%s", e.msg);
        return;
    }
    seq img = {res.width, res.height, 1, res.image};
    if (claim_output(a->out_dir, j, a->method, r->fits, sizeof r->fits) != SL_OK)
        snprintf(r->msg, sizeof r->msg, "%s: no free output name", a->out_dir);
    else if (cube_write(r->fits, &img, &res.meta, &e) != SL_OK) {
        snprintf(r->msg, sizeof r->msg, "%s", e.msg);
        unlink(r->fits); /* no row will name it */
    }
    else
        r->ok = 1;
    const pipeline_binary *b = &res.binary;
    r->found = b->status == PIPE_BIN_MEASURED || b->status == PIPE_BIN_AMBIGUOUS;
    r->sep_px = b->sep_px, r->sep_err_px = b->sep_err_px;
    r->pa_deg = b->pa_deg, r->pa_err_deg = b->pa_err_deg;
    r->dm_mag = b->dm_mag, r->dm_err_mag = b->dm_err_mag;
    r->ran = res.report.method;
    r->nframes = res.nframes, r->width = res.width, r->height = res.height;
    r->plate_scale_arcsec = res.plate_scale_arcsec;
    r->elapsed_s = res.elapsed_s;
    pipeline_result_clear(&res);
}

/* Rank 0: the row, in one transaction. */
static int record(catalog *c, const rargs *a, const rjob *j, const rresult *r,
                  int nranks)
{
    char params[256], quality[256];
    snprintf(params, sizeof params, "{\"method\":\"%s\",\"ran\":\"%s\",\"reprocess\":true,"
             "\"ranks\":%d}", a->method, pipeline_method_name(r->ran), nranks);
    snprintf(quality, sizeof quality, "{\"nframes\":%d,\"width\":%d,\"height\":%d,"
             "\"binary_found\":%s}", r->nframes, r->width, r->height,
             r->found ? "true" : "false");
    catalog_recon rec;
    catalog_recon_init(&rec);
    rec.run_uuid = j->uuid;
    rec.method = a->method;
    rec.params_json = params;
    rec.started_ms = r->started_ms;
    rec.elapsed_s = r->elapsed_s;
    rec.output_fits = r->fits;
    rec.quality_json = quality;
    if (r->found) {
        rec.sep_px = r->sep_px, rec.sep_err_px = r->sep_err_px;
        rec.pa_deg = r->pa_deg, rec.pa_err_deg = r->pa_err_deg;
        rec.dm_mag = r->dm_mag, rec.dm_err_mag = r->dm_err_mag;
        if (r->plate_scale_arcsec > 0)
            rec.sep_arcsec = r->sep_px * r->plate_scale_arcsec;
    }
    return catalog_recon_insert(c, &rec, NULL);
}

typedef struct joblist {
    rjob *v;
    int n, cap;
} joblist;

static int add_run(const catalog_run *run, void *user)
{
    joblist *l = user;
    if (!run->file_path || !run->file_path[0])
        return SL_OK;
    if (l->n == l->cap) {
        int cap = l->cap ? 2 * l->cap : 64;
        rjob *v = realloc(l->v, (size_t)cap * sizeof *v);
        if (!v)
            return SL_ENOMEM;
        l->v = v, l->cap = cap;
    }
    rjob *j = &l->v[l->n];
    j->idx = l->n++;
    snprintf(j->uuid, sizeof j->uuid, "%s", run->uuid);
    snprintf(j->cube, sizeof j->cube, "%s", run->file_path);
    return SL_OK;
}

/* Rank 0's bookkeeping of a result: the row, or the failure said. */
static int take_result(catalog *c, const rargs *a, const joblist *l, const rresult *r,
                       int from, int nranks, int *nrecorded)
{
    const rjob *j = &l->v[r->idx];
    if (!r->ok) {
        fprintf(stderr, "specklab-mpi reprocess: rank %d: run %s: %s\n", from, j->uuid, r->msg);
        return SL_EDATA;
    }
    if (record(c, a, j, r, nranks) != SL_OK) {
        fprintf(stderr, "specklab-mpi reprocess: run %s: %s\n", j->uuid, catalog_errmsg(c));
        return SL_EIO;
    }
    (*nrecorded)++;
    printf("run %s: %s (rank %d), %d of %d recorded\n", j->uuid, r->fits, from,
           *nrecorded, l->n);
    fflush(stdout);
    return SL_OK;
}

/* Rank 0 with workers: hand out runs as ranks come free. */
static int lead(catalog *c, const rargs *a, const joblist *l, int nranks, int *nrecorded)
{
    int next = 0, active = nranks - 1, failed = 0;
    while (active > 0) {
        rresult r;
        MPI_Status st;
        MPI_Recv(&r, sizeof r, MPI_BYTE, MPI_ANY_SOURCE, TAG_RESULT, MPI_COMM_WORLD, &st);
        if (r.idx >= 0 && take_result(c, a, l, &r, st.MPI_SOURCE, nranks, nrecorded) != SL_OK)
            failed = 1;
        if (next < l->n) {
            MPI_Send(&l->v[next++], sizeof(rjob), MPI_BYTE, st.MPI_SOURCE, TAG_JOB, MPI_COMM_WORLD);
        } else {
            MPI_Send(NULL, 0, MPI_BYTE, st.MPI_SOURCE, TAG_STOP, MPI_COMM_WORLD);
            active--;
        }
    }
    return failed ? SL_EDATA : SL_OK;
}

static void follow(const rargs *a)
{
    rresult r = {.idx = -1};
    for (;;) {
        MPI_Send(&r, sizeof r, MPI_BYTE, 0, TAG_RESULT, MPI_COMM_WORLD);
        rjob j;
        MPI_Status st;
        MPI_Recv(&j, sizeof j, MPI_BYTE, 0, MPI_ANY_TAG, MPI_COMM_WORLD, &st);
        if (st.MPI_TAG == TAG_STOP)
            return;
        reconstruct(a, &j, &r);
    }
}

/* Rank 0: the runs to do and the output directory; SL_OK or an error said. */
static int prepare(const rargs *a, catalog **c, joblist *l)
{
    sl_err e = {0};
    int rc = catalog_open(c, a->catalog, &e);
    if (rc != SL_OK) {
        fprintf(stderr, "specklab-mpi reprocess: %s\n", e.msg);
        return rc;
    }
    catalog_run_filter f = {.state = CATALOG_DONE, .since_ms = a->since_ms};
    if ((rc = catalog_run_list(*c, &f, add_run, l)) != SL_OK) {
        fprintf(stderr, "specklab-mpi reprocess: %s\n", catalog_errmsg(*c));
        return rc;
    }
    if (g_mkdir_with_parents(a->out_dir, 0755) != 0) {
        fprintf(stderr, "specklab-mpi reprocess: %s: %s\n", a->out_dir, g_strerror(errno));
        return SL_EIO;
    }
    return SL_OK;
}

static int run_all(const mpishare *m, const rargs *a)
{
    int rank = mpishare_rank(m), n = mpishare_size(m), rc = SL_OK, nrec = 0;
    catalog *c = NULL;
    joblist l = {0};
    if (rank == 0)
        rc = prepare(a, &c, &l);
    MPI_Bcast(&rc, 1, MPI_INT, 0, MPI_COMM_WORLD); /* nobody waits on a failed start */
    if (rc != SL_OK)
        goto close_catalog;
    if (rank > 0) {
        follow(a);
    } else if (n > 1) {
        rc = lead(c, a, &l, n, &nrec);
    } else {
        for (int i = 0; i < l.n; i++) {
            rresult r;
            reconstruct(a, &l.v[i], &r);
            if (take_result(c, a, &l, &r, 0, 1, &nrec) != SL_OK)
                rc = SL_EDATA;
        }
    }
    if (rank == 0)
        printf("reprocessed %d of %d runs on %d ranks\n", nrec, l.n, n);
close_catalog:
    catalog_close(c);
    free(l.v);
    return rc == SL_OK ? 0 : 1;
}

/* Parse the options (every rank alike); 2 on a usage error. */
static int parse(int argc, char **argv, rargs *a)
{
    GOptionEntry entries[] = {
        {"catalog", 0, 0, G_OPTION_ARG_FILENAME, &a->catalog, "the catalogue (SQLite; required)", "DB"},
        {"method", 'm', 0, G_OPTION_ARG_STRING, &a->method, "direct|tsm|tsm-fourier|auto (default auto)", "M"},
        {"since", 0, 0, G_OPTION_ARG_STRING, &a->since, "only runs created at or after (ISO 8601, a date or unix seconds)", "TIME"},
        {"out-dir", 0, 0, G_OPTION_ARG_FILENAME, &a->out_dir, "where the images go (default: reprocess/ beside the catalogue)", "DIR"},
        {NULL, 0, 0, 0, NULL, NULL, NULL}};
    GOptionContext *ctx = g_option_context_new("- reconstruct catalogued runs again, over MPI ranks");
    g_option_context_add_main_entries(ctx, entries, NULL);
    int ok = cli_parse(ctx, &argc, &argv);
    g_option_context_free(ctx);
    if (!ok)
        return 2;
    sl_err e = {0};
    if (!a->catalog || argc > 1) {
        fprintf(stderr, "%s: need --catalog DB and no other argument (try --help)\n", argv[0]);
        return 2;
    }
    if (!a->method)
        a->method = g_strdup("auto");
    if (pipeline_method_parse(a->method, &a->method_id) != SL_OK) {
        fprintf(stderr, "%s: unknown --method '%s'\n", argv[0], a->method);
        return 2;
    }
    if (a->since && catalog_time_parse(a->since, &a->since_ms, &e) != SL_OK) {
        fprintf(stderr, "%s: --since: %s\n", argv[0], e.msg);
        return 2;
    }
    if (!a->out_dir) {
        char *dir = g_path_get_dirname(a->catalog);
        a->out_dir = g_build_filename(dir, "reprocess", NULL);
        g_free(dir);
    }
    return 0;
}

int reprocess_main(const mpishare *m, int argc, char **argv)
{
    rargs a = {0};
    int status = parse(argc, argv, &a);
    if (status == 0)
        status = run_all(m, &a);
    g_free(a.catalog), g_free(a.method), g_free(a.since), g_free(a.out_dir);
    return status;
}
