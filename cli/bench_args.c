/* bench_args.c - `specklab bench`'s comma-separated option lists (see
 * bench_cli.h). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "bench_cli.h"
#include "pipeline/pipeline.h"

static gchar **split(const char *s) { return g_strsplit(s, ",", -1); }

int bcli_parse_ints(const char *what, const char *s, int lo, int hi,
                    GArray *out)
{
    gchar **v = split(s);
    int rc = 0;
    for (int i = 0; v[i] && !rc; i++) {
        char *end = NULL;
        long x = strtol(v[i], &end, 10);
        if (end == v[i] || *end || x < lo || x > hi) {
            fprintf(stderr, "specklab bench: --%s '%s': expected integers "
                    "%d..%d\n", what, v[i], lo, hi);
            rc = 2;
        } else {
            int xi = (int)x;
            g_array_append_val(out, xi);
        }
    }
    g_strfreev(v);
    return rc;
}

int bcli_parse_doubles(const char *what, const char *s, GArray *out)
{
    gchar **v = split(s);
    int rc = 0;
    for (int i = 0; v[i] && !rc; i++) {
        char *end = NULL;
        double x = g_ascii_strtod(v[i], &end);
        if (end == v[i] || *end || !(x >= 0) || !isfinite(x)) {
            fprintf(stderr, "specklab bench: --%s '%s': expected numbers "
                    ">= 0\n", what, v[i]);
            rc = 2;
        } else {
            g_array_append_val(out, x);
        }
    }
    g_strfreev(v);
    return rc;
}

/* Sizes as pairs (w, h). */
int bcli_parse_sizes(const char *s, GArray *out)
{
    gchar **v = split(s);
    int rc = 0;
    for (int i = 0; v[i] && !rc; i++) {
        int wh[2];
        GError *e = NULL;
        if (!cli_parse_size(v[i], &wh[0], &wh[1], &e)) {
            fprintf(stderr, "specklab bench: %s\n", e->message);
            g_error_free(e);
            rc = 2;
        } else {
            g_array_append_vals(out, wh, 2);
        }
    }
    g_strfreev(v);
    return rc;
}

/* Skip sets "crop,support/none/all" (NULL: the methods' defaults). */
int bcli_parse_skip_sets(const char *s, GArray *out)
{
    int def = -1, rc = 0;
    if (!s) {
        g_array_append_val(out, def);
        return 0;
    }
    gchar **v = g_strsplit(s, "/", -1);
    for (int i = 0; v[i] && !rc; i++) {
        int k = -1;
        if (strcmp(v[i], "default") && pipeline_skips_parse(v[i], &k) != SL_OK) {
            fprintf(stderr, "specklab bench: --skips '%s': sets of reject, "
                    "crop, support, angles (or all, none, default) separated "
                    "by /\n", v[i]);
            rc = 2;
        } else {
            g_array_append_val(out, k);
        }
    }
    g_strfreev(v);
    return rc;
}
