/* test_cli_trust.c - the CLI never destroys data and names nonsense.
 *
 * Outputs (cli/outfile.h): an output that is an input (same name, a link,
 * a glob) is refused and the input stays byte-identical; an existing
 * output survives unless --overwrite; a failed run leaves the old file and
 * no temporary behind.  Nonsense input: each case exits non-zero with a
 * message naming what is wrong.  --json: a failure prints one object with
 * an "error" member (bin/specklab, since main() makes it).  Commands run
 * in-process with stderr in a file, except the --json ones.
 */
#define _GNU_SOURCE
#include <dirent.h>
#include <fcntl.h>
#include <libgen.h>
#include <limits.h>
#include <stdarg.h>
#include <stdlib.h>
#include <sys/stat.h>
#include <unistd.h>

#include "cli.h"
#include "io/cube.h"
#include "proc_fx.h"
#include "tcheck.h"

typedef struct tf {
    char dir[64];
    char err[4096]; /* the last command's stderr, cut */
} tf;

typedef int (*cmd_fn)(int argc, char **argv);

static int tf_start(tf *f)
{
    snprintf(f->dir, sizeof f->dir, "/tmp/sl_trust_XXXXXX");
    f->err[0] = 0;
    return mkdtemp(f->dir) ? 0 : -1;
}

static void tf_stop(tf *f)
{
    char *cmd = g_strdup_printf("rm -rf '%s'", f->dir);
    if (system(cmd) != 0)
        fprintf(stderr, "could not remove %s\n", f->dir);
    g_free(cmd);
}

static char *in_dir(const tf *f, const char *name)
{
    return g_strdup_printf("%s/%s", f->dir, name);
}

/* Run cmd(NAME, ARGS..., NULL) in-process; its status, stderr in f->err. */
static int run(tf *f, cmd_fn cmd, const char *name, ...)
{
    char *v[48], *argv[48];
    int n = 0;
    va_list ap;
    va_start(ap, name);
    v[n++] = g_strdup(name);
    for (const char *a; n < 46 && (a = va_arg(ap, const char *));)
        v[n++] = g_strdup(a);
    va_end(ap);
    v[n] = NULL;
    memcpy(argv, v, sizeof v); /* GOption reorders argv */
    char *ep = in_dir(f, "stderr.txt");
    fflush(stderr);
    int saved = dup(2), fd = open(ep, O_WRONLY | O_CREAT | O_TRUNC, 0644);
    dup2(fd, 2);
    int rc = cmd(n, argv);
    fflush(stderr);
    dup2(saved, 2);
    close(saved);
    close(fd);
    FILE *in = fopen(ep, "r");
    size_t got = in ? fread(f->err, 1, sizeof f->err - 1, in) : 0;
    f->err[got] = 0;
    if (in)
        fclose(in);
    g_free(ep);
    for (int i = 0; i < n; i++)
        g_free(v[i]);
    return rc;
}

static char *slurp(const char *path, gsize *len)
{
    char *s = NULL;
    if (!g_file_get_contents(path, &s, len, NULL))
        return NULL;
    return s;
}

/* A small binary cube (64^2 x 8 frames) in the fixture's directory. */
static int make_cube(tf *f, const char *name)
{
    char *p = in_dir(f, name);
    int rc = run(f, cmd_sim, "specklab sim", "--size", "64", "--frames", "8",
                 "--photons", "1e5", "-q", "-o", p, NULL);
    g_free(p);
    return rc;
}

/* Files in the fixture's directory whose name starts with '.': the
 * temporaries an output is written to before its rename. */
static int leftover_temporaries(const tf *f)
{
    DIR *d = opendir(f->dir);
    int n = 0;
    for (struct dirent *e; d && (e = readdir(d));)
        n += e->d_name[0] == '.' && strcmp(e->d_name, ".") && strcmp(e->d_name, "..");
    if (d)
        closedir(d);
    return n;
}

TEST(an_output_is_never_an_input)
{
    tf f;
    CHECK(tf_start(&f) == 0, "mkdtemp");
    CHECK(make_cube(&f, "c.fits") == 0, "sim: %s", f.err);
    char *c = in_dir(&f, "c.fits"), *lnk = in_dir(&f, "link.fits");
    char *glob = in_dir(&f, "*.fits");
    gsize n0 = 0, n1 = 0;
    char *before = slurp(c, &n0);
    int ok_link = symlink(c, lnk) == 0;
    int same = run(&f, cmd_recon, "specklab recon", c, "-o", c, NULL);
    int named = strstr(f.err, "is the input") != NULL;
    int via_link = run(&f, cmd_recon, "specklab recon", c, "-o", lnk, "--overwrite", NULL);
    int via_glob = run(&f, cmd_recon, "specklab recon", glob, "-o", c, "--overwrite", NULL);
    int png = run(&f, cmd_recon, "specklab recon", c, "-o", "/dev/null/x", "--png", c, NULL);
    char *after = slurp(c, &n1);
    int identical = before && after && n0 == n1 && memcmp(before, after, n0) == 0;
    g_free(before); g_free(after); g_free(c); g_free(lnk); g_free(glob);
    int tmps = leftover_temporaries(&f);
    tf_stop(&f);
    CHECK(ok_link, "symlink");
    CHECK(same == 2 && named, "recon X -o X: status %d, stderr %s", same, f.err);
    CHECK(via_link == 2 && via_glob == 2 && png == 2,
          "through a link %d, a glob %d, --png %d", via_link, via_glob, png);
    CHECK(identical, "the input changed (%zu -> %zu bytes)", (size_t)n0, (size_t)n1);
    CHECK(tmps == 0, "%d temporaries left", tmps);
}

TEST(an_existing_output_survives_without_overwrite)
{
    tf f;
    CHECK(tf_start(&f) == 0, "mkdtemp");
    CHECK(make_cube(&f, "c.fits") == 0, "sim: %s", f.err);
    char *c = in_dir(&f, "c.fits"), *o = in_dir(&f, "o.fits"), *nan = in_dir(&f, "nan.fits");
    g_file_set_contents(o, "keep me", -1, NULL);
    int refused = run(&f, cmd_recon, "specklab recon", c, "-o", o, "-m", "tsm-fourier", NULL);
    int named = strstr(f.err, "--overwrite") != NULL;
    char *kept = slurp(o, NULL);
    /* a run that fails after the check leaves the old file too */
    seq *s = seq_new(16, 16, 3);
    for (int i = 0; i < 16 * 16 * 3; i++)
        s->data[i] = NAN;
    cube_meta m;
    cube_meta_init(&m);
    sl_err e = {0};
    int wrote = cube_write(nan, s, &m, &e) == SL_OK;
    seq_free(s);
    int failed = run(&f, cmd_recon, "specklab recon", nan, "-o", o, "--overwrite", NULL);
    char *kept2 = slurp(o, NULL);
    int replaced = run(&f, cmd_recon, "specklab recon", c, "-o", o, "-m", "tsm-fourier",
                       "--overwrite", "-q", NULL);
    seq *img = NULL;
    const char *paths[] = {o};
    int readable = cube_read(&img, NULL, paths, 1, 0, &e) == SL_OK && img->width == 64 &&
                   img->height == 64 && img->nframes == 1;
    seq_free(img);
    int tmps = leftover_temporaries(&f);
    tf_stop(&f);
    int k1 = kept && !strcmp(kept, "keep me"), k2 = kept2 && !strcmp(kept2, "keep me");
    g_free(kept); g_free(kept2); g_free(c); g_free(o); g_free(nan);
    CHECK(refused == 2 && named && k1, "without --overwrite: status %d, kept %d: %s",
          refused, k1, f.err);
    CHECK(wrote && failed == 1 && k2, "failed run: status %d, kept %d", failed, k2);
    CHECK(replaced == 0 && readable, "--overwrite: status %d, image readable %d",
          replaced, readable);
    CHECK(tmps == 0, "%d temporaries left", tmps);
}

TEST(sim_and_mask_refuse_existing_files)
{
    tf f;
    CHECK(tf_start(&f) == 0, "mkdtemp");
    char *c = in_dir(&f, "c.fits"), *m = in_dir(&f, "m.txt");
    g_file_set_contents(c, "not a cube", -1, NULL);
    g_file_set_contents(m, "not a mask", -1, NULL);
    int sim = run(&f, cmd_sim, "specklab sim", "--size", "32", "--frames", "2", "-q",
                  "-o", c, NULL);
    int mask = run(&f, cmd_mask, "specklab mask", "generate", "--holes", "5",
                   "--iterations", "10", "-o", m, NULL);
    char *a = slurp(c, NULL), *b = slurp(m, NULL);
    int kept = a && b && !strcmp(a, "not a cube") && !strcmp(b, "not a mask");
    int sim2 = run(&f, cmd_sim, "specklab sim", "--size", "32", "--frames", "2", "-q",
                   "-o", c, "--overwrite", NULL);
    g_free(a); g_free(b); g_free(c); g_free(m);
    tf_stop(&f);
    CHECK(sim == 2 && mask == 2 && kept, "sim %d, mask %d, kept %d", sim, mask, kept);
    CHECK(sim2 == 0, "sim --overwrite: %d: %s", sim2, f.err);
}

/* Each nonsense input: a non-zero status and the thing named. */
TEST(nonsense_input_is_named)
{
    tf f;
    CHECK(tf_start(&f) == 0, "mkdtemp");
    CHECK(make_cube(&f, "c.fits") == 0, "sim: %s", f.err);
    char *c = in_dir(&f, "c.fits"), *o = in_dir(&f, "o.fits"), *one = in_dir(&f, "one.fits");
    char *nan = in_dir(&f, "nan.fits");
    seq *s = seq_new(64, 64, 1);
    cube_meta m;
    cube_meta_init(&m);
    sl_err e = {0};
    for (int i = 0; i < 64 * 64; i++)
        s->data[i] = (float)(i % 7);
    int w1 = cube_write(one, s, &m, &e) == SL_OK;
    seq_free(s);
    s = seq_new(64, 64, 4);
    for (int i = 0; i < 64 * 64 * 4; i++)
        s->data[i] = NAN;
    int w2 = cube_write(nan, s, &m, &e) == SL_OK;
    seq_free(s);
    struct { const char *a[8]; const char *named; } cases[] = {
        {{nan, NULL}, "no light"},
        {{one, NULL}, "1 frame"},
        {{c, "-m", "tsm", "-p", "1", NULL}, "projections 1"},
        {{c, "-m", "tsm", "-p", "100000", NULL}, "projections 100000"},
        {{c, "-m", "direct", "--r2-px", "1000", NULL}, "r2 1000"},
        {{c, "-m", "direct", "--r2-px", "-5", NULL}, "r2 -5"},
        {{c, "--wiener", "-1", NULL}, "wiener -1"},
        {{c, "-m", "direct", "--ref", c, "--target", c, NULL}, "target PSF"},
        {{c, "--target-error", "2", NULL}, "target error 2"},
    };
    char why[600] = "";
    for (size_t i = 0; i < sizeof cases / sizeof cases[0] && !why[0]; i++) {
        const char *const *a = cases[i].a;
        int rc = run(&f, cmd_recon, "specklab recon", a[0], "-o", o, a[1], a[2], a[3],
                     a[4], a[5], a[6], a[7], NULL);
        if (rc == 0 || !strstr(f.err, cases[i].named))
            snprintf(why, sizeof why, "case %zu (%s): status %d, stderr %.300s", i,
                     cases[i].named, rc, f.err);
    }
    int sim = run(&f, cmd_sim, "specklab sim", "--size", "64", "--frames", "2",
                  "--sep-arcsec", "5", "-o", o, NULL);
    int outside = strstr(f.err, "outside the 64x64 frame") != NULL;
    int wrote_o = g_file_test(o, G_FILE_TEST_EXISTS);
    g_free(c); g_free(o); g_free(one); g_free(nan);
    tf_stop(&f);
    CHECK(w1 && w2, "writing the inputs: %s", e.msg);
    CHECK(!why[0], "%s", why);
    CHECK(sim == 2 && outside, "sim companion outside: status %d: %s", sim, f.err);
    CHECK(!wrote_o, "a refused or failed run left an output");
}

/* bin/specklab ARGS --json: its status and stdout parsed. */
static int run_json(const char *const *args, JsonObject **out)
{
    char bin[PATH_MAX];
    fx_bin(bin, sizeof bin, "specklab");
    const char *argv[16] = {bin};
    int n = 1;
    for (; args[n - 1] && n < 15; n++)
        argv[n] = args[n - 1];
    argv[n] = NULL;
    char *so = NULL;
    int st = -1;
    *out = NULL;
    if (!g_spawn_sync(NULL, (char **)argv, NULL, G_SPAWN_STDERR_TO_DEV_NULL, NULL,
                      NULL, &so, NULL, &st, NULL))
        return -1;
    JsonParser *p = json_parser_new();
    if (so && json_parser_load_from_data(p, so, -1, NULL) &&
        JSON_NODE_HOLDS_OBJECT(json_parser_get_root(p)))
        *out = json_object_ref(json_node_get_object(json_parser_get_root(p)));
    g_object_unref(p);
    g_free(so);
    return WIFEXITED(st) ? WEXITSTATUS(st) : -1;
}

TEST(json_failures_are_one_object)
{
    tf f;
    CHECK(tf_start(&f) == 0, "mkdtemp");
    CHECK(make_cube(&f, "c.fits") == 0, "sim: %s", f.err);
    char *c = in_dir(&f, "c.fits"), *o = in_dir(&f, "o.fits");
    const char *usage[] = {"recon", c, "-o", o, "-p", "1", "--json", NULL};
    const char *fail[] = {"recon", "/nonexistent/x.fits", "-o", o, "--json", NULL};
    JsonObject *u = NULL, *x = NULL;
    int su = run_json(usage, &u), sx = run_json(fail, &x);
    JsonObject *eu = u && json_object_has_member(u, "error") ?
                     json_object_get_object_member(u, "error") : NULL;
    JsonObject *ex = x && json_object_has_member(x, "error") ?
                     json_object_get_object_member(x, "error") : NULL;
    int good_u = eu && json_object_get_int_member(eu, "status") == 2 &&
                 !strcmp(json_object_get_string_member(eu, "kind"), "usage") &&
                 strstr(json_object_get_string_member(eu, "message"), "projections 1");
    int good_x = ex && json_object_get_int_member(ex, "status") == 1 &&
                 !strcmp(json_object_get_string_member(ex, "kind"), "failure") &&
                 strstr(json_object_get_string_member(ex, "message"), "/nonexistent/x.fits");
    if (u) json_object_unref(u);
    if (x) json_object_unref(x);
    g_free(c); g_free(o);
    tf_stop(&f);
    CHECK(su == 2 && good_u, "usage error: status %d, object %s", su, eu ? "bad" : "absent");
    CHECK(sx == 1 && good_x, "failure: status %d, object %s", sx, ex ? "bad" : "absent");
}

TC_MAIN(TC_CASE(an_output_is_never_an_input),
        TC_CASE(an_existing_output_survives_without_overwrite),
        TC_CASE(sim_and_mask_refuse_existing_files), TC_CASE(nonsense_input_is_named),
        TC_CASE(json_failures_are_one_object))
