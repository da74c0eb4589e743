/* test_wisdom.c - wisdom round trip: after import, MEASURE planning of the
 * same transform needs no measuring (FFTW_WISDOM_ONLY succeeds). */
#include <fftw3.h>
#include <stdlib.h>
#include <unistd.h>

#include "tcheck.h"
#include "base/wisdom.h"

TEST(wisdom_round_trip)
{
    char dir[] = "/tmp/sl_wisXXXXXX", path[64], f[80];
    CHECK(mkdtemp(dir), "mkdtemp");
    snprintf(path, sizeof path, "%s/sub/w", dir);
    sl_err e;
    int loaded = -1;
    CHECK(wisdom_load(path, &loaded, &e) == SL_OK && loaded == 0, "missing file: %s", e.msg);
    float *in = fftwf_alloc_real(96 * 80);
    fftwf_complex *out = fftwf_alloc_complex(96 * 41);
    /* Not known before measuring ... */
    fftwf_plan p = fftwf_plan_dft_r2c_2d(96, 80, in, out, FFTW_MEASURE | FFTW_WISDOM_ONLY);
    CHECK(p == NULL, "wisdom present before measuring");
    p = fftwf_plan_dft_r2c_2d(96, 80, in, out, FFTW_MEASURE);
    fftwf_destroy_plan(p);
    CHECK(wisdom_save(path, &e) == SL_OK, "%s", e.msg);
    fftwf_forget_wisdom();
    CHECK(wisdom_load(path, &loaded, &e) == SL_OK && loaded == 2, "%s (loaded %d)", e.msg, loaded);
    /* ... and known after the round trip. */
    p = fftwf_plan_dft_r2c_2d(96, 80, in, out, FFTW_MEASURE | FFTW_WISDOM_ONLY);
    CHECK(p != NULL, "imported wisdom does not cover the measured plan");
    fftwf_destroy_plan(p);
    /* A corrupt file is an error that names it. */
    snprintf(f, sizeof f, "%s.f", path);
    FILE *fp = fopen(f, "w");
    fputs("not wisdom", fp);
    fclose(fp);
    CHECK(wisdom_load(path, &loaded, &e) == SL_EFORMAT && strstr(e.msg, f), "%s", e.msg);
    unlink(f);
    snprintf(f, sizeof f, "%s.d", path);
    unlink(f);
    snprintf(f, sizeof f, "%s/sub", dir);
    rmdir(f);
    rmdir(dir);
    fftwf_free(in);
    fftwf_free(out);
}

TC_MAIN(TC_CASE(wisdom_round_trip))
