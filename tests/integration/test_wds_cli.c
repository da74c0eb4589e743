/* test_wds_cli.c - `specklab binary --wds` (cli/wds.h): the line of a
 * simulated binary cube parsed back against the truth and the header's
 * date; an unresolved image says 'unresolved' and no numbers; an equal
 * pair's PA is flagged Q; a cube without a plate scale is refused naming
 * PLTSCALE; no DATE-OBS gives 'nodate' and says so. */
#include <stdlib.h>

#include "base/utcdate.h"
#include "cmdrun_fx.h"
#include "io/cube.h"
#include "wds.h"

typedef struct line {
    char date[32], flag[8], method[64];
    double theta, etheta, rho, erho, dm, edm;
    int nnum;
} line;

static void parse(const char *s, line *l)
{
    memset(l, 0, sizeof *l);
    l->nnum = sscanf(s, "%31s %lf %lf %lf %lf %lf %lf %7s %63s", l->date, &l->theta,
                     &l->etheta, &l->rho, &l->erho, &l->dm, &l->edm, l->flag, l->method);
}

TEST(binary_cube_line_matches_the_truth)
{
    fx f;
    CHECK(fx_start(&f) == 0, "mkdtemp");
    char *cube = path_in(&f, "bin.fits");
    int rs = run(&f, cmd_sim, "sim", "--scene", "binary", "--sep-arcsec", "0.2", "--pa-deg",
                 "30", "--size", "128", "--frames", "100", "--photons", "1e5", "-q", "-o",
                 cube, NULL);
    int rw = rs ? -1 : run(&f, cmd_binary, "binary", "--wds", cube, NULL);
    char out[4096];
    snprintf(out, sizeof out, "%.2047s%.2047s", f.out, f.err);
    cube_meta m;
    cube_meta_init(&m);
    cube_reader *cr = NULL;
    sl_err e = {0};
    if (cube_reader_open(&cr, (const char **)&cube, 1, 0, &e) == SL_OK)
        m = *cube_reader_meta(cr);
    cube_reader_free(cr);
    g_free(cube);
    fx_stop(&f);
    CHECK(rs == 0 && rw == 0, "sim %d, binary --wds %d: %s", rs, rw, out);
    line l;
    parse(out, &l);
    double mjd = 0;
    CHECK(utcdate_mjd(m.date_obs, &mjd, &e) == SL_OK, "DATE-OBS '%s'", m.date_obs);
    printf("  %s", out);
    CHECK(l.nnum == 9, "a line of 9 fields: '%s'", out);
    CHECK(fabs(atof(l.date) - utcdate_besselian_year(mjd)) < 1e-4, "epoch %s for %s",
          l.date, m.date_obs);
    CHECK(!strcmp(l.flag, "-") && !strcmp(l.method, "speckle/closure"), "flag '%s' "
          "method '%s'", l.flag, l.method);
    CHECK(l.etheta > 0 && l.erho > 0 && l.edm > 0, "errors %g %g %g", l.etheta, l.erho,
          l.edm);
    CHECK(fabs(l.theta - 30) < 3 * l.etheta + 0.3 && fabs(l.rho - 0.2) < 3 * l.erho + 0.002 &&
          fabs(l.dm - 1) < 3 * l.edm + 0.05, "theta %.2f +- %.2f, rho %.4f +- %.4f, dm "
          "%.2f +- %.2f against 30, 0.2, 1", l.theta, l.etheta, l.rho, l.erho, l.dm, l.edm);
}

TEST(unresolved_ambiguous_and_refused)
{
    fx f;
    CHECK(fx_start(&f) == 0, "mkdtemp");
    char *pt = path_in(&f, "pt.fits"), *eq = path_in(&f, "eq.fits");
    char *blind = path_in(&f, "blind.fits"), *pair = path_in(&f, "pair.txt");
    /* an equal pair 0.3" apart at PA 30 (or 210) */
    FILE *sf = fopen(pair, "w");
    if (sf) {
        fprintf(sf, "point 0.075 -0.12990381 1\npoint -0.075 0.12990381 1\n");
        fclose(sf);
    }
    int r0 = run(&f, cmd_sim, "sim", "--scene", "point", "--size", "64", "--frames", "2",
                 "-q", "-o", pt, NULL);
    r0 |= run(&f, cmd_sim, "sim", "--scene", pair, "--size", "64", "--frames", "2", "-q",
              "-o", eq, NULL);
    r0 |= run(&f, cmd_sim, "sim", "--size", "64", "--frames", "2", "--blind", "-q", "-o",
              blind, NULL);
    char o1[512], o2[512], e3[512];
    /* the sky itself: one star, nothing beside it */
    int r1 = run(&f, cmd_binary, "binary", "--wds", pt, "--ext", "TRUTH", NULL);
    snprintf(o1, sizeof o1, "%.511s", f.out);
    /* an equal pair through the cophased mask: which star is which is unknown */
    int r2 = run(&f, cmd_binary, "binary", "--wds", eq, "--ext", "COPHASED", NULL);
    snprintf(o2, sizeof o2, "%.511s", f.out);
    int r3 = run(&f, cmd_binary, "binary", "--wds", blind, NULL);
    snprintf(e3, sizeof e3, "%.511s", f.err);
    g_free(pt);
    g_free(eq);
    g_free(blind);
    g_free(pair);
    fx_stop(&f);
    CHECK(r0 == 0, "sim");
    line l;
    parse(o1, &l);
    CHECK(r1 == 1 && strstr(o1, " unresolved ") && l.nnum == 1, "unresolved: %d '%s'", r1, o1);
    parse(o2, &l);
    CHECK(r2 == 0 && l.nnum == 9 && !strcmp(l.flag, "Q") && fabs(l.rho - 0.3) < 0.01,
          "equal pair: %d '%s'", r2, o2);
    CHECK(fabs(remainder(l.theta - 30, 180)) < 1, "equal pair theta %.2f: 30 or 210", l.theta);
    CHECK(r3 == 1 && strstr(e3, "PLTSCALE"), "no plate scale: %d '%s'", r3, e3);
}

TEST(no_date_says_so)
{
    cube_meta m;
    cube_meta_init(&m);
    pipeline_binary v;
    memset(&v, 0, sizeof v);
    v.status = PIPE_BIN_MEASURED, v.source = PIPE_BIN_SRC_CLOSURE;
    v.sep_px = 4, v.sep_err_px = 0.05, v.pa_deg = -10, v.pa_err_deg = 0.5;
    v.dm_mag = 1, v.dm_err_mag = 0.03;
    wds_measure w;
    sl_err e = {0};
    CHECK(wds_measure_from(&v, 0.05, &m, 100, &w, &e) == SL_OK, "%s", e.msg);
    char buf[512];
    wds_format(&w, buf, sizeof buf);
    line l;
    parse(buf, &l);
    CHECK(!strcmp(l.date, "nodate") && strstr(buf, "no DATE-OBS") && l.theta == 350 &&
          l.rho == 0.2, "'%s'", buf);
    snprintf(m.date_obs, sizeof m.date_obs, "2026-13-01");
    CHECK(wds_measure_from(&v, 0.05, &m, 100, &w, &e) == SL_EINVAL && strstr(e.msg, "DATE-OBS"),
          "bad date: %s", e.msg);
    m.date_obs[0] = 0;
    CHECK(wds_measure_from(&v, NAN, &m, 100, &w, &e) == SL_EINVAL && strstr(e.msg, "PLTSCALE"),
          "no plate scale: %s", e.msg);
    v.status = PIPE_BIN_INCONSISTENT;
    snprintf(v.why, sizeof v.why, "image fit 7.87 px at 116.2 deg");
    wds_measure_from(&v, 0.05, &m, 100, &w, &e);
    wds_format(&w, buf, sizeof buf);
    parse(buf, &l);
    CHECK(l.nnum == 1 && strstr(buf, "inconsistent") && strstr(buf, "7.87 px"), "'%s'", buf);
}

TC_MAIN(TC_CASE(binary_cube_line_matches_the_truth), TC_CASE(unresolved_ambiguous_and_refused),
        TC_CASE(no_date_says_so))
