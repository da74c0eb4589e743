/* test_daemon_recon.c - `specklab recon RUN-ID` with recon's options,
 * through specklabd (daemon/recon_opts.h), on a simulated bench:
 *   options_through_the_daemon  `recon RUN -m auto --skips all
 *                     --tsm-inverse iter --binary` is done by the daemon,
 *                     the reconstruction's params carry exactly those
 *                     options and what auto ran, and the binary is measured;
 *                     a bad option gets the words `recon CUBE` prints for
 *                     it, exit 2, and no reconstruction row; an option the
 *                     daemon checks against its range (-p 1) likewise.
 */
#include "daemon_fx.h"

#include <glib.h>

static int has(const char *hay, const char *needle)
{
    return hay && needle && strstr(hay, needle) != NULL;
}

/* bin/specklab with args (NULL-terminated), with the bench's socket when
 * b is not NULL: exit status, stdout and stderr (g_free). */
static int specklab(bench *b, char **out, char **err, ...)
{
    char bin[PATH_MAX];
    fx_bin(bin, sizeof bin, "specklab");
    GPtrArray *v = g_ptr_array_new();
    g_ptr_array_add(v, bin);
    va_list ap;
    va_start(ap, err);
    for (const char *a; (a = va_arg(ap, const char *));)
        g_ptr_array_add(v, (char *)a);
    va_end(ap);
    if (b) {
        g_ptr_array_add(v, "--socket");
        g_ptr_array_add(v, b->sock);
    }
    g_ptr_array_add(v, NULL);
    int st = -1;
    gboolean ok = g_spawn_sync(NULL, (char **)v->pdata, NULL, G_SPAWN_DEFAULT, NULL, NULL,
                               out, err, &st, NULL);
    g_ptr_array_free(v, TRUE);
    return ok && WIFEXITED(st) ? WEXITSTATUS(st) : -1;
}

/* The last line of text that holds needle, for a message. */
static int same_error(const char *a, const char *b, const char *needle)
{
    const char *pa = a ? strstr(a, needle) : NULL, *pb = b ? strstr(b, needle) : NULL;
    if (!pa || !pb)
        return 0;
    size_t na = strcspn(pa, "\n"), nb = strcspn(pb, "\n");
    return na == nb && !strncmp(pa, pb, na);
}

static int nrecons(bench *b, dc *c, const char *uuid)
{
    char args[96];
    snprintf(args, sizeof args, "{\"run\": \"%s\"}", uuid);
    JsonNode *r = keep(b, dc_call(c, "run", args, 5));
    int n = 0;
    char path[48];
    for (; n < 50; n++) {
        snprintf(path, sizeof path, "result.reconstructions.%d", n);
        if (!jget(r, path))
            break;
    }
    return n;
}

BENCH_TEST(options_through_the_daemon, 180, NULL, NULL)
{
    dc *c = bench_client(b);
    CHECK(c && bench_wait_camera(b, c, 20) == 0, "no daemon or no camera");
    keep(b, dc_call(c, "subscribe", NULL, 5));
    JsonNode *r = keep(b, dc_call(c, "start-run", "{\"screen\": 1, \"mask\": 1, \"frames\": 60, "
                                  "\"reconstruct\": \"none\"}", 5));
    CHECK(jok(r), "start-run: %s", jtext(r));
    char uuid[40];
    snprintf(uuid, sizeof uuid, "%s", js(r, "result.run"));
    JsonNode *e = keep(b, dc_wait_state(c, uuid, "done,failed,aborted", 60, NULL, NULL));
    CHECK(e && has(js(e, "state"), "done"), "run: %s", jtext(e));

    char *out = NULL, *err = NULL;
    int rc = specklab(b, &out, &err, "recon", uuid, "-m", "auto", "--skips", "all",
                      "--tsm-inverse", "iter", "--binary", "--json", NULL);
    JsonNode *res = out ? keep(b, json_from_string(out, NULL)) : NULL;
    g_free(out);
    CHECK(rc == 0 && res, "recon RUN -m auto ...: exit %d, %s", rc, err ? err : "");
    g_free(err);
    JsonNode *x = jget(res, "reconstruction");
    CHECK(x && has(js(x, "params.method"), "auto") && !jget(x, "params.options.method") &&
          has(js(x, "params.options.skips"), "all") &&
          has(js(x, "params.options.tsm-inverse"), "iter") &&
          has(js(x, "params.options.binary"), "true") && js(x, "params.ran") &&
          has(js(x, "params.skips"), "reject,crop,support,angles"),
          "params %s", jtext(jget(x, "params")));
    CHECK(has(js(x, "method"), "auto") && has(js(x, "params.binary_status"), "measured"),
          "reconstruction %s", jtext(x));
    /* the truth-free quality every reconstruction carries */
    double cp = jd(x, "quality.closure_rms_deg");
    CHECK(isfinite(cp) && cp >= 0 && cp < 90 && ji(x, "quality.closure_triples") > 0,
          "quality %s", jtext(jget(x, "quality")));
    int before = nrecons(b, c, uuid);

    /* a bad choice: the words recon prints for a cube, through the socket */
    char *dout = NULL, *derr = NULL, *lout = NULL, *lerr = NULL;
    int drc = specklab(b, &dout, &derr, "recon", uuid, "--window", "bogus", NULL);
    int lrc = specklab(NULL, &lout, &lerr, "recon", "/nonexistent.fits", "-o", "/tmp/x.fits",
                       "--window", "bogus", NULL);
    int same = same_error(derr, lerr, "unknown --window 'bogus'");
    CHECK(drc == 2 && lrc == 2 && same, "daemon: exit %d '%s'; cube: exit %d '%s'", drc,
          derr ? derr : "", lrc, lerr ? lerr : "");
    g_free(dout), g_free(derr), g_free(lout), g_free(lerr);
    /* a value out of range: pipeline_opts_check's words */
    drc = specklab(b, &dout, &derr, "recon", uuid, "-p", "1", NULL);
    lrc = specklab(NULL, &lout, &lerr, "recon", "/nonexistent.fits", "-o", "/tmp/x.fits", "-p",
                   "1", NULL);
    same = same_error(derr, lerr, "projections 1");
    CHECK(drc == 2 && lrc == 2 && same, "daemon: exit %d '%s'; cube: exit %d '%s'", drc,
          derr ? derr : "", lrc, lerr ? lerr : "");
    g_free(dout), g_free(derr), g_free(lout), g_free(lerr);
    /* a raw client: a flag that is not true/false, an unknown option */
    char args[256];
    snprintf(args, sizeof args, "{\"run\": \"%s\", \"options\": {\"binary\": \"maybe\"}}", uuid);
    r = keep(b, dc_call(c, "reconstruct", args, 5));
    CHECK(!jok(r) && has(js(r, "error.message"), "--binary"), "binary maybe: %s", jtext(r));
    snprintf(args, sizeof args, "{\"run\": \"%s\", \"options\": {\"ref\": \"x.fits\"}}", uuid);
    r = keep(b, dc_call(c, "reconstruct", args, 5));
    CHECK(!jok(r) && has(js(r, "error.message"), "unknown option --ref"), "ref: %s", jtext(r));
    CHECK(nrecons(b, c, uuid) == before, "a refused request left a reconstruction");
}

TC_MAIN(TC_CASE(options_through_the_daemon))
