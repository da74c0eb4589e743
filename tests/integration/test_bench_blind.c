/* test_bench_blind.c - `specklab bench --blind --quick` as a harness: it
 * runs in-process (cmd_bench; each point still forks), exits 0, prints a
 * row per condition x method and the summary, and writes a CSV whose rows
 * parse, one per condition x method of blind_matrix's quick subset, in
 * order, with a finite c wherever the run succeeded and a summary that
 * counts what the CSV says.  The reconstructor's accuracy is not asserted
 * here (it is what the bench measures). */
#include <fcntl.h>
#include <stdarg.h>
#include <stdlib.h>
#include <unistd.h>

#include "bench_blind.h"
#include "cli.h"
#include "pipeline/pipeline.h"
#include "tcheck.h"

static const char *const methods[] = {"direct", "tsm-fourier", "tsm", "auto"};
#define NMETHODS 4

typedef struct fx {
    char dir[64];
    char *out, *err; /* the last command's stdout and stderr (g_free) */
} fx;

static int fx_start(fx *f)
{
    memset(f, 0, sizeof *f);
    snprintf(f->dir, sizeof f->dir, "/tmp/sl_blindcli_XXXXXX");
    return mkdtemp(f->dir) ? 0 : -1;
}

static void fx_stop(fx *f)
{
    char *cmd = g_strdup_printf("rm -rf '%s'", f->dir);
    if (system(cmd) != 0)
        fprintf(stderr, "could not remove %s\n", f->dir);
    g_free(cmd);
    g_free(f->out);
    g_free(f->err);
}

/* `specklab bench ARGS... NULL` in-process, stdout and stderr captured. */
static int bench(fx *f, ...)
{
    char *v[32], *argv[32];
    int n = 0;
    va_list ap;
    va_start(ap, f);
    v[n++] = g_strdup("specklab bench");
    for (const char *a; n < 30 && (a = va_arg(ap, const char *));)
        v[n++] = g_strdup(a);
    va_end(ap);
    v[n] = NULL;
    memcpy(argv, v, sizeof v); /* GOption reorders argv */
    char *po = g_strdup_printf("%s/out.txt", f->dir), *pe = g_strdup_printf("%s/err.txt", f->dir);
    fflush(stdout);
    fflush(stderr);
    int so = dup(1), se = dup(2);
    int fo = open(po, O_WRONLY | O_CREAT | O_TRUNC, 0644);
    int fe = open(pe, O_WRONLY | O_CREAT | O_TRUNC, 0644);
    dup2(fo, 1);
    dup2(fe, 2);
    int rc = cmd_bench(n, argv);
    fflush(stdout);
    fflush(stderr);
    dup2(so, 1);
    dup2(se, 2);
    close(so);
    close(se);
    close(fo);
    close(fe);
    g_free(f->out);
    g_free(f->err);
    f->out = f->err = NULL;
    g_file_get_contents(po, &f->out, NULL, NULL);
    g_file_get_contents(pe, &f->err, NULL, NULL);
    g_free(po);
    g_free(pe);
    for (int i = 0; i < n; i++)
        g_free(v[i]);
    return rc;
}

static int column(gchar **head, const char *name)
{
    for (int i = 0; head[i]; i++)
        if (!strcmp(head[i], name))
            return i;
    return -1;
}

/* "summary METHOD: binary within K/N" -> K and N; 0 when absent. */
static int summary_within(const char *out, const char *method, int *k, int *n)
{
    char key[64];
    snprintf(key, sizeof key, "summary %s: binary within ", method);
    const char *p = strstr(out, key);
    return p && sscanf(p + strlen(key), "%d/%d", k, n) == 2;
}

/* Lines of out starting with "name " (table rows of a condition). */
static int rows_of(const char *out, const char *name)
{
    int count = 0;
    size_t len = strlen(name);
    for (const char *p = out; p && *p; p = strchr(p, '\n') ? strchr(p, '\n') + 1 : NULL)
        count += !strncmp(p, name, len) && p[len] == ' ';
    return count;
}

TEST(quick_blind_bench_writes_a_row_per_condition_and_method)
{
    fx f;
    CHECK(fx_start(&f) == 0, "mkdtemp");
    char *csv = g_strdup_printf("%s/blind.csv", f.dir);
    int rc = bench(&f, "--blind", "--quick", "--csv", csv, NULL);
    gchar *text = NULL;
    g_file_get_contents(csv, &text, NULL, NULL);
    g_free(csv);
    blind_cond conds[BLIND_MAX_CONDITIONS];
    int ncond = blind_matrix(1, 1, conds, BLIND_MAX_CONDITIONS);
    gchar **lines = text ? g_strsplit(text, "\n", -1) : NULL;
    gchar **head = lines ? g_strsplit(lines[0], ",", -1) : NULL;
    int ncol = head ? (int)g_strv_length(head) : 0;
    int cc = head ? column(head, "condition") : -1, cm = head ? column(head, "method") : -1;
    int cs = head ? column(head, "status") : -1, cv = head ? column(head, "c") : -1;
    int c1 = head ? column(head, "one_minus_c") : -1, cw = head ? column(head, "within") : -1;
    int ct = head ? column(head, "true_sep_px") : -1;
    int ok_rows = 0, within[NMETHODS] = {0}, nbin = 0, bad_row = -1;
    char why[256] = "";
    for (int i = 0; i < ncond; i++)
        nbin += !strcmp(conds[i].sim.scene, "binary");
    int nrows = lines ? (int)g_strv_length(lines) - 1 : 0;
    if (nrows > 0 && lines[nrows][0] == 0)
        nrows--; /* the final newline */
    for (int r = 0; r < nrows && bad_row < 0; r++) {
        gchar **v = g_strsplit(lines[r + 1], ",", -1);
        int k = r % NMETHODS, cond = r / NMETHODS;
        int fields = (int)g_strv_length(v);
        if (fields != ncol || cond >= ncond) {
            snprintf(why, sizeof why, "%d fields of %d", fields, ncol);
            bad_row = r;
        } else if (strcmp(v[cc], conds[cond].name) || strcmp(v[cm], methods[k])) {
            snprintf(why, sizeof why, "%s/%s, expected %s/%s", v[cc], v[cm],
                     conds[cond].name, methods[k]);
            bad_row = r;
        } else if (!strcmp(v[cs], "ok")) {
            char *end;
            double c = g_ascii_strtod(v[cv], &end), e1 = g_ascii_strtod(v[c1], NULL);
            if (end == v[cv] || !isfinite(c) || fabs(c) > 1 || fabs(c + e1 - 1) > 1e-5) {
                snprintf(why, sizeof why, "ok but c '%s', 1-c '%s'", v[cv], v[c1]);
                bad_row = r;
            }
            ok_rows++;
        } else if (strcmp(v[cs], "failed")) {
            snprintf(why, sizeof why, "status '%s'", v[cs]);
            bad_row = r;
        }
        if (bad_row < 0 && !strcmp(conds[cond].sim.scene, "binary")) {
            within[k] += !strcmp(v[cw], "1");
            /* 6 lambda/D at Nyquist is 12 px, whatever the mask */
            if (fabs(g_ascii_strtod(v[ct], NULL) - 12) > 1e-6) {
                snprintf(why, sizeof why, "true_sep_px %s", v[ct]);
                bad_row = r;
            }
        }
        g_strfreev(v);
    }
    g_strfreev(lines);
    g_strfreev(head);
    g_free(text);
    int table_ok = 1;
    for (int i = 0; f.out && i < ncond; i++)
        table_ok &= rows_of(f.out, conds[i].name) == NMETHODS;
    int sk[NMETHODS] = {0}, sn[NMETHODS] = {0}, have_summary = 1;
    for (int k = 0; k < NMETHODS; k++)
        have_summary &= f.out && summary_within(f.out, methods[k], &sk[k], &sn[k]);
    int auto_line = f.out && strstr(f.out, "summary auto target: achieved 1-c <= 0.1 in ");
    char err_text[300];
    snprintf(err_text, sizeof err_text, "%s", f.err ? f.err : "");
    fx_stop(&f);
    CHECK(rc == 0, "exit %d: %s", rc, err_text);
    CHECK(ncond == 4 && ncol > 40 && cc == 0 && cm >= 0 && cs >= 0 && cv >= 0 && c1 >= 0 &&
          cw >= 0 && ct >= 0, "%d conditions, %d columns", ncond, ncol);
    CHECK(nrows == ncond * NMETHODS, "%d CSV rows for %d conditions x %d methods", nrows,
          ncond, NMETHODS);
    CHECK(bad_row < 0, "CSV row %d: %s", bad_row + 1, why);
    CHECK(ok_rows > 0, "no run succeeded");
    CHECK(table_ok, "the table lacks a row per condition and method");
    CHECK(have_summary && auto_line, "summary lines missing");
    for (int k = 0; k < NMETHODS; k++)
        CHECK(sn[k] == nbin && sk[k] == within[k], "summary %s: within %d/%d, the CSV says "
              "%d/%d", methods[k], sk[k], sn[k], within[k], nbin);
}

/* Options that belong to the other presets are refused with --blind, and
 * --conditions names what the matrix has. */
TEST(blind_option_errors_are_named)
{
    fx f;
    CHECK(fx_start(&f) == 0, "mkdtemp");
    int rp = bench(&f, "--blind", "--paper", NULL);
    int paper_named = f.err && strstr(f.err, "--blind runs its own matrix");
    int rc = bench(&f, "--blind", "--conditions", "baseline,nope", "--csv", "none", NULL);
    int listed = f.err && strstr(f.err, "'nope'") && strstr(f.err, "hot-50");
    int rn = bench(&f, "--conditions", "baseline", NULL);
    int needs = f.err && strstr(f.err, "--conditions needs --blind");
    int rm = bench(&f, "--blind", "--methods", "direct,fast", "--csv", "none", NULL);
    int method_named = f.err && strstr(f.err, "'fast'");
    int rt = bench(&f, "--blind", "--target-error", "0.1,0.2", "--csv", "none", NULL);
    int target_named = f.err && strstr(f.err, "--target-error '0.1,0.2'");
    /* an existing CSV: refused before the matrix runs, left as it was */
    char *csv = g_strdup_printf("%s/kept.csv", f.dir);
    g_file_set_contents(csv, "earlier results\n", -1, NULL);
    int rx = bench(&f, "--blind", "--quick", "--csv", csv, NULL);
    int exists_named = f.err && strstr(f.err, "kept.csv") && strstr(f.err, "--overwrite") &&
                       f.out && !strstr(f.out, "baseline");
    gchar *kept = NULL;
    g_file_get_contents(csv, &kept, NULL, NULL);
    g_free(csv);
    fx_stop(&f);
    CHECK(rx == 2 && exists_named && kept && !strcmp(kept, "earlier results\n"),
          "an existing CSV: exit %d, named %d, now '%s'", rx, exists_named, kept ? kept : "");
    g_free(kept);
    CHECK(rp == 2 && paper_named, "--paper: exit %d", rp);
    CHECK(rc == 2 && listed, "--conditions nope: exit %d", rc);
    CHECK(rn == 2 && needs, "--conditions without --blind: exit %d", rn);
    CHECK(rm == 2 && method_named, "--methods fast: exit %d", rm);
    CHECK(rt == 2 && target_named, "--target-error 0.1,0.2: exit %d", rt);
}

TC_MAIN(TC_CASE(quick_blind_bench_writes_a_row_per_condition_and_method),
        TC_CASE(blind_option_errors_are_named))
