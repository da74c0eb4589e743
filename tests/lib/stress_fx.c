/* stress_fx.c - see stress_fx.h. */
#include "stress_fx.h"

int stress_full(void)
{
    const char *v = getenv("SL_STRESS_FULL");
    return v && *v && strcmp(v, "0") != 0;
}

int fx_open(fx *f)
{
    return tmp_make(f) ? 0 : -1;
}

void fx_close(fx *f)
{
    tmp_remove(f);
}

const char *fx_path(fx *f, int slot, const char *name)
{
    return tmp_path(f, slot, name);
}

bench_sim fx_binary(int w, int h, int n, double photons)
{
    bench_sim s;
    bench_sim_defaults(&s);
    s.width = w;
    s.height = h;
    s.nframes = n;
    s.photons = photons;
    return s;
}

int fx_sim(const bench_sim *s, const char *path, const char *psf)
{
    sl_err e = {0};
    int rc = bench_sim_write(s, path, psf, &e);
    if (rc != SL_OK)
        fprintf(stderr, "fx_sim %s: %s\n", path, e.msg);
    return rc;
}

int fx_recon(const char *cube, int method, int nangles, const char *ref, const char *target,
             pipeline_result *r, sl_err *e)
{
    pipeline_opts o;
    pipeline_opts_defaults(&o);
    o.method = method;
    o.nangles = nangles;
    o.ref_path = ref;
    o.target_path = target;
    o.fftw_measure = 0;
    const char *paths[] = {cube};
    return pipeline_run(paths, 1, &o, r, e);
}

int fx_finite(const float *img, size_t n)
{
    for (size_t i = 0; i < n; i++)
        if (!isfinite(img[i]))
            return 0;
    return 1;
}

int fx_binary_err(const char *cube, const float *img, double *dsep, double *dpa, double *ddm)
{
    bench_truth tr;
    bench_score s;
    sl_err e = {0};
    *dsep = *dpa = *ddm = NAN;
    int rc = bench_truth_read(&tr, cube, &e);
    if (rc != SL_OK)
        return rc;
    rc = bench_score_image(img, &tr, BENCH_HP_SIGMA_PX, &s, &e);
    bench_truth_clear(&tr);
    if (rc != SL_OK)
        return rc;
    if (!s.binary_found)
        return SL_EDATA;
    *dsep = s.sep_err_px;
    *dpa = s.pa_err_deg;
    *ddm = s.dm_err_mag;
    return SL_OK;
}

int fx_rewrite(const char *in, const char *out, void (*fn)(seq *s, void *u), void *u)
{
    seq *s = NULL;
    cube_meta m;
    sl_err e = {0};
    const char *paths[] = {in};
    int rc = cube_read(&s, &m, paths, 1, CUBE_ALLOW_NONFINITE, &e);
    if (rc == SL_OK) {
        fn(s, u);
        rc = cube_write(out, s, &m, &e);
    }
    if (rc != SL_OK)
        fprintf(stderr, "fx_rewrite %s: %s\n", out, e.msg);
    seq_free(s);
    return rc;
}
