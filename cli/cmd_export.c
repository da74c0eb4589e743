/* cmd_export.c - `specklab export RUN-ID` (the run's FITS, its
 * reconstructions and a JSON sidecar, copied into a directory) and
 * `specklab recon RUN-ID` (on-demand reconstruction by the daemon). */
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "cli.h"
#include "cmd_daemon.h"
#include "outfile.h"
#include "pipeline/pipeline.h"

#define COPY_CHUNK (1 << 20)
/* On-demand reconstruction of a long cube can take minutes. */
#define RECON_TIMEOUT_S 1800

/* The daemon may report paths relative to its own working directory: on
 * the same host that directory is /proc/PID/cwd (readable when we share
 * its user, or are root).  Otherwise the path is used as given. */
static char *resolve_path(client *c, const char *path)
{
    if (g_path_is_absolute(path) || g_file_test(path, G_FILE_TEST_EXISTS))
        return g_strdup(path);
    long pid = client_peer_pid(c);
    if (pid > 0) {
        char *p = g_strdup_printf("/proc/%ld/cwd/%s", pid, path);
        if (g_file_test(p, G_FILE_TEST_EXISTS))
            return p;
        g_free(p);
    }
    return g_strdup(path);
}

/* Every byte of in to out; 0, or -1 with *err set. */
static int copy_bytes(int in, const char *src, int out, const char *dst,
                      char *buf, GChecksum *sum, char **err)
{
    for (;;) {
        ssize_t n = read(in, buf, COPY_CHUNK);
        if (n < 0 && errno == EINTR)
            continue;
        if (n < 0) {
            *err = g_strdup_printf("reading %s: %s", src, strerror(errno));
            return -1;
        }
        if (n == 0)
            return 0;
        if (sum)
            g_checksum_update(sum, (const guchar *)buf, n);
        for (ssize_t off = 0; off < n;) {
            ssize_t w = write(out, buf + off, (size_t)(n - off));
            if (w < 0 && errno == EINTR)
                continue;
            if (w < 0) {
                *err = g_strdup_printf("writing %s: %s", dst, strerror(errno));
                return -1;
            }
            off += w;
        }
    }
}

/* Copy src to dst by outfile.h's rules (never over an input, an existing
 * dst only with overwrite, through a temporary and rename) with an fsync
 * before the rename, so DIR never holds a half-copied FITS under its real
 * name; sum (may be NULL) sees every byte. */
static int copy_file(const char *src, const char *dst, int overwrite,
                     GChecksum *sum, char **err)
{
    outfile of;
    GError *ge = NULL;
    const char *in[] = {src};
    if (!outfile_begin(&of, dst, overwrite, in, 1, &ge)) {
        *err = g_strdup(ge->message);
        g_error_free(ge);
        return -1;
    }
    int rc = -1, fd = open(src, O_RDONLY | O_CLOEXEC), out = -1;
    char *buf = g_malloc(COPY_CHUNK);
    if (fd < 0) {
        *err = g_strdup_printf("%s: %s", src, strerror(errno));
        goto free_buf;
    }
    out = open(of.tmp, O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0644);
    if (out < 0) {
        *err = g_strdup_printf("%s: %s", of.tmp, strerror(errno));
        goto close_in;
    }
    rc = copy_bytes(fd, src, out, of.tmp, buf, sum, err);
    if (rc == 0 && fsync(out) < 0) {
        *err = g_strdup_printf("fsync %s: %s", of.tmp, strerror(errno));
        rc = -1;
    }
    if (close(out) < 0 && rc == 0) {
        *err = g_strdup_printf("closing %s: %s", of.tmp, strerror(errno));
        rc = -1;
    }
    if (rc == 0 && !outfile_commit(&of, &ge)) {
        *err = g_strdup(ge->message);
        g_error_free(ge);
        rc = -1;
    }
close_in:
    close(fd);
free_buf:
    g_free(buf);
    outfile_clear(&of);
    return rc;
}

/* Copy the daemon's file at path into dir as name; the exported name is
 * added to files (for the sidecar).  0 or 1 (message printed). */
static int export_one(client *c, const char *path, const char *dir, const char *name,
                      int overwrite, GChecksum *sum, JsonArray *files)
{
    char *src = resolve_path(c, path), *err = NULL;
    char *dst = g_build_filename(dir, name, NULL);
    int rc = copy_file(src, dst, overwrite, sum, &err);
    if (rc != 0) {
        fprintf(stderr, "specklab export: %s\n", err);
        g_free(err);
    } else {
        json_array_add_string_element(files, dst);
    }
    g_free(src);
    g_free(dst);
    return rc != 0;
}

/* "runs/<uuid>.fits" -> "<uuid>.fits"; recon outputs whose basename is
 * taken already get "r<ID>-" in front. */
static char *export_name(const char *path, gint64 id, GHashTable *used)
{
    char *base = g_path_get_basename(path);
    if (g_hash_table_contains(used, base)) {
        char *b = g_strdup_printf("r%lld-%s", (long long)id, base);
        g_free(base);
        base = b;
    }
    g_hash_table_add(used, g_strdup(base));
    return base;
}

static int write_sidecar(const char *path, JsonObject *res, JsonObject *exp)
{
    JsonObject *all = json_object_new();
    JsonObject *run = dcmd_obj(res, "run");
    JsonArray *recs = dcmd_arr(res, "reconstructions");
    json_object_set_object_member(all, "run", run ? json_object_ref(run) : json_object_new());
    json_object_set_array_member(all, "reconstructions",
                                 recs ? json_array_ref(recs) : json_array_new());
    json_object_set_object_member(all, "export", json_object_ref(exp));
    JsonNode *n = json_node_init_object(json_node_alloc(), all);
    JsonGenerator *g = json_generator_new();
    json_generator_set_root(g, n);
    json_generator_set_pretty(g, TRUE);
    gsize len = 0;
    gchar *text = json_generator_to_data(g, &len);
    GError *ge = NULL;
    int rc = 0;
    if (!g_file_set_contents(path, text, (gssize)len, &ge)) {
        fprintf(stderr, "specklab export: %s\n", ge->message);
        g_error_free(ge);
        rc = 1;
    }
    g_free(text);
    g_object_unref(g);
    json_node_unref(n);
    json_object_unref(all);
    return rc;
}

/* Copy everything of the run (res = the `run` reply) into dir. */
/* Every file export_run would write, checked before the first is copied
 * (outfile.h), so a refusal never leaves half an export. */
static int check_destinations(JsonObject *res, const char *dir, const char *uuid,
                              int overwrite)
{
    GHashTable *used = g_hash_table_new_full(g_str_hash, g_str_equal, g_free, NULL);
    GPtrArray *dst = g_ptr_array_new_with_free_func(g_free);
    const char *file = dcmd_str(dcmd_obj(res, "run"), "file");
    if (file)
        g_ptr_array_add(dst, export_name(file, 0, used));
    JsonArray *recs = dcmd_arr(res, "reconstructions");
    for (guint i = 0; recs && i < json_array_get_length(recs); i++) {
        JsonObject *x = json_array_get_object_element(recs, i);
        const char *outs[] = {dcmd_str(x, "fits"), dcmd_str(x, "png")};
        for (int k = 0; k < 2; k++)
            if (outs[k])
                g_ptr_array_add(dst, export_name(outs[k], dcmd_int(x, "id", i), used));
    }
    g_ptr_array_add(dst, g_strdup_printf("%s.json", uuid));
    GError *ge = NULL;
    int ok = 1;
    for (guint i = 0; ok && i < dst->len; i++) {
        char *path = g_build_filename(dir, (const char *)dst->pdata[i], NULL);
        ok = outfile_check(path, overwrite, NULL, 0, &ge);
        g_free(path);
    }
    if (!ok) {
        fprintf(stderr, "specklab export: %s\n", ge->message);
        g_error_free(ge);
    }
    g_ptr_array_free(dst, TRUE);
    g_hash_table_destroy(used);
    return ok;
}

/* What was exported, as a JSON object or lines. */
static void export_report(const char *uuid, const char *dir, JsonArray *files,
                          const char *side, int verified, int status, int json)
{
    if (json) {
        JsonObject *o = json_object_new();
        json_object_set_string_member(o, "run", uuid);
        json_object_set_string_member(o, "dir", dir);
        json_object_set_array_member(o, "files", json_array_ref(files));
        json_object_set_string_member(o, "sidecar", side);
        json_object_set_boolean_member(o, "ok", status == 0);
        dcmd_print_object(o);
        json_object_unref(o);
        return;
    }
    printf("run %s exported to %s:\n", uuid, dir);
    for (guint i = 0; i < json_array_get_length(files); i++)
        printf("  %s%s\n", json_array_get_string_element(files, i),
               i == 0 && verified ? "  (sha256 verified)" : "");
    printf("  %s\n", side);
}

static int export_run(client *c, JsonObject *res, const char *dir, int json,
                      int overwrite)
{
    JsonObject *run = dcmd_obj(res, "run");
    const char *uuid = dcmd_str(run, "uuid");
    if (!uuid) {
        fprintf(stderr, "specklab export: the daemon's run record has no uuid\n");
        return 1;
    }
    if (g_mkdir_with_parents(dir, 0755) < 0) {
        fprintf(stderr, "specklab export: cannot create %s: %s\n", dir, strerror(errno));
        return 1;
    }
    if (!check_destinations(res, dir, uuid, overwrite))
        return 2;
    int status = 0;
    JsonObject *exp = json_object_new();
    JsonArray *files = json_array_new();
    GHashTable *used = g_hash_table_new_full(g_str_hash, g_str_equal, g_free, NULL);
    const char *file = dcmd_str(run, "file"), *want = dcmd_str(run, "sha256");
    if (file) {
        GChecksum *sum = g_checksum_new(G_CHECKSUM_SHA256);
        char *name = export_name(file, 0, used);
        status |= export_one(c, file, dir, name, overwrite, sum, files);
        if (!status && want) {
            int same = !g_ascii_strcasecmp(g_checksum_get_string(sum), want);
            json_object_set_boolean_member(exp, "sha256_verified", same);
            if (!same) {
                fprintf(stderr, "specklab export: %s: sha256 %s differs from the "
                        "catalogue's %s\n", file, g_checksum_get_string(sum), want);
                status = 1;
            }
        } else {
            json_object_set_null_member(exp, "sha256_verified");
        }
        g_checksum_free(sum);
        g_free(name);
    } else {
        fprintf(stderr, "specklab export: run %s has no file (state %s): sidecar only\n",
                uuid, dcmd_str(run, "state") ? dcmd_str(run, "state") : "?");
    }
    JsonArray *recs = dcmd_arr(res, "reconstructions");
    for (guint i = 0; recs && i < json_array_get_length(recs); i++) {
        JsonObject *x = json_array_get_object_element(recs, i);
        const char *outs[] = {dcmd_str(x, "fits"), dcmd_str(x, "png")};
        for (int k = 0; k < 2; k++) {
            if (!outs[k])
                continue;
            char *name = export_name(outs[k], dcmd_int(x, "id", i), used);
            status |= export_one(c, outs[k], dir, name, overwrite, NULL, files);
            g_free(name);
        }
    }
    char *side = g_strdup_printf("%s/%s.json", dir, uuid);
    GDateTime *now = g_date_time_new_now_utc();
    char *at = g_date_time_format(now, "%Y-%m-%dT%H:%M:%SZ");
    json_object_set_string_member(exp, "exported", at);
    json_object_set_string_member(exp, "socket", client_path(c));
    json_object_set_array_member(exp, "files", json_array_ref(files));
    status |= write_sidecar(side, res, exp);
    export_report(uuid, dir, files, side, file && want && !status, status, json);
    g_free(at);
    g_date_time_unref(now);
    g_free(side);
    g_hash_table_destroy(used);
    json_array_unref(files);
    json_object_unref(exp);
    return status;
}

int cmd_export(int argc, char **argv)
{
    dcmd_opts o = {0};
    char *dir = NULL;
    int overwrite = 0;
    GOptionEntry entries[] = {
        {"output", 'o', 0, G_OPTION_ARG_FILENAME, &dir, "directory to write into (default .)", "DIR"},
        {"overwrite", 0, 0, G_OPTION_ARG_NONE, &overwrite, "replace files already in DIR", NULL},
        {NULL, 0, 0, 0, NULL, NULL, NULL}};
    GOptionContext *ctx = g_option_context_new("RUN-ID - copy a run's FITS and reconstructions, with a JSON sidecar");
    g_option_context_add_main_entries(ctx, entries, NULL);
    dcmd_opts_add(&o, ctx);
    g_option_context_set_description(ctx,
        "Writes DIR/<file>.fits (sha256 checked against the catalogue), each\n"
        "reconstruction's FITS and PNG, and DIR/<uuid>.json with the run and\n"
        "reconstruction records.");
    int status = 2;
    client *c = NULL;
    JsonObject *args = json_object_new(), *res = NULL;
    if (!cli_parse(ctx, &argc, &argv))
        goto free_args;
    if (argc != 2) {
        fprintf(stderr, "specklab export: usage: specklab export RUN-ID [-o DIR]\n");
        goto free_args;
    }
    json_object_set_string_member(args, "run", argv[1]);
    status = 1;
    if (!(c = dcmd_connect(&o, "specklab export")) ||
        dcmd_call(c, "specklab export", "run", args, DCMD_QUERY_MS, &res))
        goto free_client;
    status = export_run(c, res, dir ? dir : ".", o.json, overwrite);
    json_object_unref(res);
free_client:
    client_free(c);
free_args:
    json_object_unref(args);
    g_option_context_free(ctx);
    dcmd_opts_clear(&o);
    g_free(dir);
    return status;
}

/* ---- specklab recon RUN-ID ---- */

static void print_recon(const char *run, JsonObject *x)
{
    char a[32], b[32], p[32], pe[32], d[32], de[32], c[32], t[32];
    printf("run %s: %s reconstruction #%lld in %s s\n", run,
           dcmd_str(x, "method") ? dcmd_str(x, "method") : "?",
           (long long)dcmd_int(x, "id", -1), dcmd_fmt(t, sizeof t, "%.2f", dcmd_num(x, "elapsed_s")));
    printf("  sep %s\" (%s px), PA %s +- %s deg, dm %s +- %s mag, closure residual %s deg\n",
           dcmd_fmt(a, sizeof a, "%.4f", dcmd_num(x, "sep_arcsec")),
           dcmd_fmt(b, sizeof b, "%.3f", dcmd_num(x, "sep_px")),
           dcmd_fmt(p, sizeof p, "%.2f", dcmd_num(x, "pa_deg")),
           dcmd_fmt(pe, sizeof pe, "%.2f", dcmd_num(x, "pa_err_deg")),
           dcmd_fmt(d, sizeof d, "%.3f", dcmd_num(x, "dm_mag")),
           dcmd_fmt(de, sizeof de, "%.3f", dcmd_num(x, "dm_err_mag")),
           dcmd_fmt(c, sizeof c, "%.2f", dcmd_num(dcmd_obj(x, "quality"), "closure_rms_deg")));
    if (dcmd_str(x, "fits"))
        printf("  %s\n", dcmd_str(x, "fits"));
    if (dcmd_str(x, "png"))
        printf("  %s\n", dcmd_str(x, "png"));
}

/* -o / --png: copy the daemon's output where the user asked. */
static int copy_out(client *c, JsonObject *x, const char *key, const char *dst,
                    int overwrite)
{
    const char *src = dcmd_str(x, key);
    if (!dst)
        return 0;
    if (!src) {
        fprintf(stderr, "specklab recon: the daemon wrote no %s for this reconstruction\n", key);
        return 1;
    }
    char *path = resolve_path(c, src), *err = NULL;
    int rc = copy_file(path, dst, overwrite, NULL, &err);
    if (rc != 0) {
        fprintf(stderr, "specklab recon: %s\n", err);
        g_free(err);
    }
    g_free(path);
    return rc != 0;
}

#define RUN_OPTS_MAX 32

/* recon's reconstruction options for a catalogued run: every name
 * pipeline_opts_set knows (the daemon parses them with it), as text, with
 * recon's -m and -p.  Files are not among them: they would be paths on
 * this machine, not the daemon's. */
typedef struct run_opts {
    GOptionEntry e[RUN_OPTS_MAX + 1];
    char *text[RUN_OPTS_MAX];
    gboolean flag[RUN_OPTS_MAX];
    int n;
} run_opts;

static void run_opts_init(run_opts *r)
{
    memset(r, 0, sizeof *r);
    int is_flag;
    const char *name;
    for (int i = 0; r->n < RUN_OPTS_MAX && (name = pipeline_opts_name(i, &is_flag)); i++) {
        GOptionEntry *e = &r->e[r->n];
        e->long_name = name;
        e->short_name = !strcmp(name, "method") ? 'm' : !strcmp(name, "projections") ? 'p' : 0;
        e->arg = is_flag ? G_OPTION_ARG_NONE : G_OPTION_ARG_STRING;
        e->arg_data = is_flag ? (gpointer)&r->flag[r->n] : (gpointer)&r->text[r->n];
        e->description = is_flag ? "as for a cube (specklab recon --help)"
                                  : "as for a cube (specklab recon --help); checked by the daemon";
        e->arg_description = is_flag ? NULL : "V";
        r->n++;
    }
}

/* The options given into args: the method as the command's own argument
 * (as before options existed), the rest as its "options" object. */
static void run_opts_json(const run_opts *r, JsonObject *args)
{
    JsonObject *o = NULL;
    for (int i = 0; i < r->n; i++) {
        const char *name = r->e[i].long_name;
        if (!r->text[i] && !r->flag[i])
            continue;
        if (!strcmp(name, "method")) {
            json_object_set_string_member(args, name, r->text[i]);
            continue;
        }
        if (!o)
            o = json_object_new();
        json_object_set_string_member(o, name, r->text[i] ? r->text[i] : "true");
    }
    if (o)
        json_object_set_object_member(args, "options", o);
}

static void run_opts_clear(run_opts *r)
{
    for (int i = 0; i < r->n; i++)
        g_free(r->text[i]);
}

/* -o and --png checked before the daemon spends minutes on the run. */
static int outputs_free(const char *out, const char *png, int overwrite)
{
    GError *ge = NULL;
    if ((out && !outfile_check(out, overwrite, NULL, 0, &ge)) ||
        (png && !outfile_check(png, overwrite, NULL, 0, &ge))) {
        fprintf(stderr, "specklab recon: %s\n", ge->message);
        g_error_free(ge);
        return 0;
    }
    return 1;
}

int cmd_recon_run(int argc, char **argv)
{
    dcmd_opts o = {0};
    run_opts ro;
    char *out = NULL, *png = NULL;
    int quiet = 0, overwrite = 0, timeout_s = RECON_TIMEOUT_S;
    GOptionEntry entries[] = {
        {"output", 'o', 0, G_OPTION_ARG_FILENAME, &out, "also copy the reconstruction FITS here", "FILE"},
        {"png", 0, 0, G_OPTION_ARG_FILENAME, &png, "also copy the PNG preview here", "FILE"},
        {"overwrite", 0, 0, G_OPTION_ARG_NONE, &overwrite, "replace existing -o/--png files", NULL},
        {"timeout-s", 0, 0, G_OPTION_ARG_INT, &timeout_s, "give up after S s (default 1800)", "S"},
        {"quiet", 'q', 0, G_OPTION_ARG_NONE, &quiet, "print nothing on success", NULL},
        {NULL, 0, 0, 0, NULL, NULL, NULL}};
    run_opts_init(&ro);
    GOptionContext *ctx = g_option_context_new("RUN-ID - reconstruct a catalogued run in the daemon");
    g_option_context_add_main_entries(ctx, entries, NULL);
    g_option_context_add_main_entries(ctx, ro.e, NULL);
    dcmd_opts_add(&o, ctx);
    g_option_context_set_description(ctx,
        "The result is stored as a new reconstruction row of the run, with the options\n"
        "given; the daemon checks them as recon does for a cube.  Calibration frames and\n"
        "a reference come from its configuration and catalogue (calibrator runs).");
    int status = 2;
    client *c = NULL;
    JsonObject *args = json_object_new(), *res = NULL;
    if (!cli_parse(ctx, &argc, &argv))
        goto free_args;
    if (argc != 2 || timeout_s <= 0) {
        fprintf(stderr, "specklab recon: usage: specklab recon RUN-ID [--method M] "
                        "[recon's options] [-o FILE] [--png FILE]\n");
        goto free_args;
    }
    if (!outputs_free(out, png, overwrite))
        goto free_args;
    json_object_set_string_member(args, "run", argv[1]);
    run_opts_json(&ro, args);
    status = 1;
    if (!(c = dcmd_connect(&o, "specklab recon")))
        goto free_args;
    if (isatty(STDERR_FILENO) && !quiet && !o.json)
        fprintf(stderr, "specklab recon: reconstructing run %s in specklabd...\n", argv[1]);
    if (dcmd_call(c, "specklab recon", "reconstruct", args, timeout_s * 1000, &res)) {
        /* a refused option is a usage error, as for a cube */
        status = g_strcmp0(client_errcode(c), "bad-request") ? 1 : 2;
        goto free_client;
    }
    JsonObject *x = dcmd_obj(res, "reconstruction");
    const char *run = dcmd_str(res, "run") ? dcmd_str(res, "run") : argv[1];
    status = copy_out(c, x, "fits", out, overwrite) | copy_out(c, x, "png", png, overwrite);
    if (o.json)
        dcmd_print_object(res);
    else if (!quiet && x)
        print_recon(run, x);
    json_object_unref(res);
free_client:
    client_free(c);
free_args:
    json_object_unref(args);
    g_option_context_free(ctx);
    dcmd_opts_clear(&o);
    run_opts_clear(&ro);
    g_free(out); g_free(png);
    return status;
}
