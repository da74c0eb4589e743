/* test_cube.c - FITS frame I/O: round trips, streaming, crash safety,
 * errors, and the real A 258 frames checked against a hand-decoded read. */
#include "io/cube.h"
#include "tcheck.h"
#include "tmpdir_fx.h"

#include <fitsio.h>
#include <signal.h>
#include <stdint.h>
#include <stdlib.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

/* ---- helpers ----------------------------------------------------------- */

/* A seq whose pixel values all differ: v = base + x + 10 y + 100 k. */
static seq *pattern_seq(int w, int h, int n, float base)
{
    seq *s = seq_new(w, h, n);
    for (int k = 0; s && k < n; k++)
        for (int y = 0; y < h; y++)
            for (int x = 0; x < w; x++)
                seq_frame(s, k)[y * w + x] = base + x + 10.0f * y + 100.0f * k;
    return s;
}

static int seq_equal(const seq *a, const seq *b)
{
    return a->width == b->width && a->height == b->height &&
           a->nframes == b->nframes &&
           memcmp(a->data, b->data, seq_frame_pixels(a) * (size_t)a->nframes *
                  sizeof(float)) == 0;
}

/* Write a FITS image of any shape straight through cfitsio. */
static int raw_image(const char *path, int bitpix, int naxis, long *naxes)
{
    fitsfile *fp;
    int st = 0;
    long n = 1;
    for (int i = 0; i < naxis; i++)
        n *= naxes[i];
    float *v = calloc((size_t)n, sizeof *v);
    unlink(path);
    fits_create_diskfile(&fp, path, &st);
    fits_create_img(fp, bitpix, naxis, naxes, &st);
    fits_write_img(fp, TFLOAT, 1, n, v, &st);
    fits_close_file(fp, &st);
    free(v);
    return st;
}

/* ---- round trips ------------------------------------------------------- */

/* Values exactly representable both as float and in the file type. */
static float typed_value(int bitpix, int i)
{
    static const float u8[] = {0, 1, 127, 128, 254, 255};
    static const float i16[] = {-32768, -1, 0, 1, 12345, 32767};
    static const float u16[] = {0, 1, 32767, 32768, 55000, 65535};
    static const float i32[] = {-2147483648.0f, -16777216.0f,
                                -1, 0, 16777216, 2147483520.0f};
    static const float u32[] = {0, 1, 2147483648.0f, 16777216, 4294967040.0f,
                                65536};
    static const float f32[] = {-3.4e38f, -1.5f, 0.1f, 1e-38f, 1.4e-45f,
                                3.4028235e38f};
    const float *t = bitpix == 8 ? u8 : bitpix == 16 ? i16
                   : bitpix == CUBE_BITPIX_U16 ? u16 : bitpix == 32 ? i32
                   : bitpix == CUBE_BITPIX_U32 ? u32 : f32;
    return i < 6 ? t[i] : t[i % 6] + (bitpix < 0 ? 0.25f * (float)i : 0.0f);
}

static int physical_header(const char *path, int *bitpix, double *bzero)
{
    fitsfile *fp;
    int st = 0;
    *bzero = 0.0;
    fits_open_diskfile(&fp, path, READONLY, &st);
    fits_get_img_type(fp, bitpix, &st);
    if (fits_read_key(fp, TDOUBLE, "BZERO", bzero, NULL, &st) == KEY_NO_EXIST)
        st = 0;
    fits_close_file(fp, &st);
    return st;
}

TEST(every_bitpix_round_trips_exactly)
{
    static const int codes[] = {8, 16, CUBE_BITPIX_U16, 32, CUBE_BITPIX_U32,
                                -32, -64};
    static const int stored[] = {8, 16, 16, 32, 32, -32, -64};
    static const double zero[] = {0, 0, 32768, 0, 2147483648.0, 0, 0};
    tmpdir d;
    CHECK(tmp_make(&d), "mkdtemp");
    const char *path = tmp_path(&d, 0, "bp.fits");
    for (size_t c = 0; c < sizeof codes / sizeof codes[0]; c++) {
        seq *in = seq_new(4, 3, 3), *out = NULL;
        for (int i = 0; i < 36; i++)
            in->data[i] = typed_value(codes[c], i);
        cube_writer *w = NULL;
        sl_err e = {0};
        int rc = cube_writer_open(&w, path, 4, 3, codes[c], NULL, &e);
        for (int k = 0; rc == SL_OK && k < 3; k++)
            rc = cube_writer_append(w, seq_frame(in, k));
        if (rc == SL_OK)
            rc = cube_writer_close(w);
        cube_writer_free(w);
        if (rc == SL_OK)
            rc = cube_read(&out, NULL, &path, 1, 0, &e);
        int bp = 0;
        double bz = -1;
        int ok = rc == SL_OK && seq_equal(in, out) &&
                 physical_header(path, &bp, &bz) == 0;
        seq_free(in);
        seq_free(out);
        CHECK(ok, "bitpix %d: rc %d %s", codes[c], rc, e.msg);
        CHECK(bp == stored[c] && bz == zero[c], "bitpix %d stored as BITPIX "
              "%d BZERO %g", codes[c], bp, bz);
    }
    tmp_remove(&d);
}

TEST(integer_types_round_and_refuse_out_of_range)
{
    tmpdir d;
    CHECK(tmp_make(&d), "mkdtemp");
    const char *path = tmp_path(&d, 0, "r.fits");
    float good[4] = {2.6f, -2.6f, 2.4f, -0.5f}, bad[4] = {1, 40000, 2, 3};
    float nan4[4] = {0, 0, NAN, 0};
    cube_writer *w = NULL;
    seq *s = NULL;
    sl_err e = {0};
    int rc = cube_writer_open(&w, path, 2, 2, 16, NULL, &e);
    CHECK(rc == SL_OK, "%s", e.msg);
    int rc_bad = cube_writer_append(w, bad);
    int n_after_bad = cube_writer_nframes(w);
    char msg[SL_ERRMSG_MAX];
    snprintf(msg, sizeof msg, "%s", cube_writer_errmsg(w));
    int rc_nan = cube_writer_append(w, nan4);
    rc = cube_writer_append(w, good);
    rc = rc ? rc : cube_writer_close(w);
    cube_writer_free(w);
    CHECK(rc_bad == SL_ERANGE && n_after_bad == 0, "rc %d n %d", rc_bad,
          n_after_bad);
    CHECK(strstr(msg, "(1, 0)") && strstr(msg, "40000"), "%s", msg);
    CHECK(rc_nan == SL_ERANGE && rc == SL_OK, "nan %d, good %d", rc_nan, rc);
    rc = cube_read(&s, NULL, &path, 1, 0, &e);
    CHECK(rc == SL_OK && s->nframes == 1, "%s", e.msg);
    /* cfitsio rounds half away from zero */
    int ok = s->data[0] == 3 && s->data[1] == -3 && s->data[2] == 2 &&
             s->data[3] == -1;
    seq_free(s);
    tmp_remove(&d);
    CHECK(ok, "rounding: %g %g %g %g", good[0], good[1], good[2], good[3]);
}

static void fill_meta(cube_meta *m)
{
    cube_meta_init(m);
    snprintf(m->date_obs, sizeof m->date_obs, "2024-05-06T01:02:03.456");
    m->exptime_s = 0.001;
    snprintf(m->instrume, sizeof m->instrume, "ZWO ASI290MM");
    snprintf(m->object, sizeof m->object, "STF 1234 AB");
    snprintf(m->bunit, sizeof m->bunit, "ADU");
    m->plate_scale_arcsec = 0.0371;
    m->wavelength_m = 6.56281e-7;
    cube_meta_set_num(m, "SEED", 123456789, "simulation seed");
    cube_meta_set_num(m, "r0_m", 0.1, "[m] Fried parameter");
    cube_meta_set_num(m, "TINY", -1.2345678901234567e-300, NULL);
    cube_meta_set_str(m, "SIMNAME", "  O'Brien's star", "leading blanks");
    cube_meta_set_str(m, "LONGSTR", "0123456789012345678901234567890123456789"
                      "0123456789012345678901234567", NULL);
}

/* Equal, with NaN (absent) equal to NaN. */
static int num_same(double a, double b)
{
    return a == b || (isnan(a) && isnan(b));
}

static int meta_same(const cube_meta *a, const cube_meta *b)
{
    int same = !strcmp(a->date_obs, b->date_obs) &&
               num_same(a->exptime_s, b->exptime_s) &&
               !strcmp(a->instrume, b->instrume) &&
               !strcmp(a->object, b->object) && !strcmp(a->bunit, b->bunit) &&
               num_same(a->plate_scale_arcsec, b->plate_scale_arcsec) &&
               num_same(a->wavelength_m, b->wavelength_m) &&
               a->nextra == b->nextra;
    for (int i = 0; same && i < a->nextra; i++) {
        const cube_kv *x = &a->extra[i], *y = &b->extra[i];
        same = !strcmp(x->key, y->key) && x->type == y->type &&
               x->num == y->num && !strcmp(x->str, y->str) &&
               !strcmp(x->comment, y->comment);
    }
    return same;
}

TEST(metadata_and_extras_round_trip)
{
    tmpdir d;
    cube_meta m, got, again;
    sl_err e = {0};
    seq *s = pattern_seq(5, 4, 2, 0), *back = NULL;
    CHECK(tmp_make(&d), "mkdtemp");
    const char *p1 = tmp_path(&d, 0, "m1.fits"), *p2 = tmp_path(&d, 1, "m2.fits");
    fill_meta(&m);
    CHECK(m.nextra == 5 && strcmp(m.extra[1].key, "R0_M") == 0, "set");
    int rc = cube_write(p1, s, &m, &e);
    rc = rc ? rc : cube_read(&back, &got, &p1, 1, 0, &e);
    seq_free(back);
    back = NULL;
    rc = rc ? rc : cube_write(p2, s, &got, &e);
    rc = rc ? rc : cube_read(&back, &again, &p2, 1, 0, &e);
    seq_free(s);
    seq_free(back);
    tmp_remove(&d);
    CHECK(rc == SL_OK, "%s", e.msg);
    CHECK(meta_same(&m, &got), "first round trip differs");
    CHECK(meta_same(&m, &again), "second round trip differs");
    const char *str = NULL;
    double v = 0;
    CHECK(cube_meta_get_num(&got, "r0_m", &v) == SL_OK && v == 0.1, "r0");
    CHECK(cube_meta_get_str(&got, "SIMNAME", &str) == SL_OK &&
          !strcmp(str, "  O'Brien's star"), "string");
}

TEST(meta_setters_validate_keys)
{
    cube_meta m;
    cube_meta_init(&m);
    CHECK(isnan(m.exptime_s) && isnan(m.plate_scale_arcsec) &&
          isnan(m.wavelength_m) && m.date_obs[0] == 0, "init");
    CHECK(cube_meta_set_num(&m, "NAXIS1", 3, NULL) == SL_EINVAL, "NAXIS1");
    CHECK(cube_meta_set_num(&m, "BZERO", 3, NULL) == SL_EINVAL, "BZERO");
    CHECK(cube_meta_set_num(&m, "EXPTIME", 3, NULL) == SL_EINVAL, "EXPTIME");
    CHECK(cube_meta_set_num(&m, "NINECHARS", 3, NULL) == SL_EINVAL, "9");
    CHECK(cube_meta_set_num(&m, "A B", 3, NULL) == SL_EINVAL, "space");
    CHECK(cube_meta_set_num(&m, "X", NAN, NULL) == SL_EINVAL, "nan");
    CHECK(cube_meta_set_str(&m, "X", "012345678901234567890123456789012345678"
          "901234567890123456789012345678", NULL) == SL_ERANGE, "69 chars");
    CHECK(cube_meta_set_num(&m, "GAIN", 1, NULL) == SL_OK, "add");
    CHECK(cube_meta_set_str(&m, "gain", "high", "c") == SL_OK, "replace");
    const char *s = NULL;
    double v = 0;
    CHECK(m.nextra == 1 && cube_meta_get_str(&m, "GAIN", &s) == SL_OK &&
          !strcmp(s, "high"), "replaced in place");
    CHECK(cube_meta_get_num(&m, "GAIN", &v) == SL_EDATA, "type");
    CHECK(cube_meta_get_num(&m, "NOPE", &v) == SL_EINVAL, "absent");
    char key[16];
    int rc = SL_OK;
    for (int i = 1; i < CUBE_META_MAX_EXTRA && rc == SL_OK; i++) {
        snprintf(key, sizeof key, "K%d", i);
        rc = cube_meta_set_num(&m, key, i, NULL);
    }
    CHECK(rc == SL_OK && m.nextra == CUBE_META_MAX_EXTRA, "fill %d", rc);
    CHECK(cube_meta_set_num(&m, "ONEMORE", 1, NULL) == SL_ERANGE, "full");
}

/* A header written by another program: logicals, commentary cards, a
 * Fortran exponent, a quoted EXPTIME, BLANK pixels, data in extension 1. */
static int foreign_file(const char *path)
{
    fitsfile *fp;
    int st = 0;
    long nx[2] = {3, 2};
    short px[6] = {1, 2, -999, 4, 5, 6};
    unlink(path);
    fits_create_diskfile(&fp, path, &st);
    fits_create_img(fp, 8, 0, NULL, &st);
    fits_create_img(fp, SHORT_IMG, 2, nx, &st);
    fits_update_key_log(fp, "FLAG", 1, "a logical", &st);
    fits_write_history(fp, "made by hand", &st);
    fits_write_comment(fp, "a comment card", &st);
    fits_write_record(fp, "DVAL    =              1.5D+02 / fortran", &st);
    fits_update_key_str(fp, "EXPTIME", "0.25", NULL, &st);
    fits_update_key_lng(fp, "BLANK", -999, NULL, &st);
    fits_write_img(fp, TSHORT, 1, 6, px, &st);
    fits_close_file(fp, &st);
    return st;
}

TEST(foreign_keywords_and_extension_data)
{
    tmpdir d;
    cube_meta m, m2;
    seq *s = NULL, *s2 = NULL;
    sl_err e = {0};
    double v = 0;
    CHECK(tmp_make(&d), "mkdtemp");
    const char *p = tmp_path(&d, 0, "f.fits"), *q = tmp_path(&d, 1, "g.fits");
    CHECK(foreign_file(p) == 0, "cfitsio");
    int rc_strict = cube_read(&s, NULL, &p, 1, 0, &e);
    int rc = cube_read(&s, &m, &p, 1, CUBE_ALLOW_NONFINITE, &e);
    rc = rc ? rc : cube_write(q, s, &m, &e);
    rc = rc ? rc : cube_read(&s2, &m2, &q, 1, CUBE_ALLOW_NONFINITE, &e);
    int data_ok = rc == SL_OK && s->width == 3 && s->height == 2 &&
                  s->data[0] == 1 && isnan(s->data[2]) && s->data[5] == 6;
    seq_free(s);
    seq_free(s2);
    tmp_remove(&d);
    CHECK(rc_strict == SL_EDATA, "BLANK pixel should be NaN: %d", rc_strict);
    CHECK(rc == SL_OK && data_ok, "%s", e.msg);
    CHECK(m.exptime_s == 0.25, "quoted EXPTIME %g", m.exptime_s);
    CHECK(cube_meta_get_num(&m, "DVAL", &v) == SL_OK && v == 150, "D exp");
    CHECK(m.nextra == 2 && m.extra[0].type == CUBE_KV_BOOL &&
          m.extra[0].num == 1, "FLAG, DVAL only; got %d", m.nextra);
    CHECK(cube_meta_get_num(&m, "BLANK", &v) == SL_EINVAL, "BLANK kept");
    CHECK(m.date_obs[0] == 0 && m2.date_obs[0] != 0, "DATE-OBS added");
    memcpy(m.date_obs, m2.date_obs, sizeof m.date_obs);
    CHECK(meta_same(&m, &m2), "re-written file differs");
}

TEST(extras_beyond_the_bound_are_counted)
{
    tmpdir d;
    fitsfile *fp;
    int st = 0;
    long nx[2] = {2, 2};
    char key[16];
    cube_meta m;
    seq *s = NULL;
    sl_err e = {0};
    CHECK(tmp_make(&d), "mkdtemp");
    const char *p = tmp_path(&d, 0, "many.fits");
    CHECK(raw_image(p, -32, 2, nx) == 0, "setup");
    fits_open_diskfile(&fp, p, READWRITE, &st);
    for (int i = 0; i < CUBE_META_MAX_EXTRA + 6; i++) {
        snprintf(key, sizeof key, "K%d", i);
        fits_update_key_lng(fp, key, i, NULL, &st);
    }
    fits_close_file(fp, &st);
    int rc = cube_read(&s, &m, &p, 1, 0, &e);
    seq_free(s);
    tmp_remove(&d);
    CHECK(st == 0 && rc == SL_OK, "%d %s", st, e.msg);
    snprintf(key, sizeof key, "K%d", CUBE_META_MAX_EXTRA - 1);
    CHECK(m.nextra == CUBE_META_MAX_EXTRA && m.ndropped == 6 &&
          !strcmp(m.extra[CUBE_META_MAX_EXTRA - 1].key, key),
          "kept %d dropped %d", m.nextra, m.ndropped);
}

TEST(default_date_and_naxis)
{
    tmpdir d;
    cube_meta m;
    seq *one = pattern_seq(3, 3, 1, 0), *got = NULL;
    sl_err e = {0};
    int naxis = 0, st = 0;
    fitsfile *fp;
    CHECK(tmp_make(&d), "mkdtemp");
    const char *p = tmp_path(&d, 0, "one.fits");
    int rc = cube_write(p, one, NULL, &e);
    rc = rc ? rc : cube_read(&got, &m, &p, 1, 0, &e);
    fits_open_diskfile(&fp, p, READONLY, &st);
    fits_get_img_dim(fp, &naxis, &st);
    fits_close_file(fp, &st);
    int same = rc == SL_OK && seq_equal(one, got);
    seq_free(one);
    seq_free(got);
    tmp_remove(&d);
    CHECK(same, "%s", e.msg);
    CHECK(naxis == 2, "a one-frame seq is a 2-D image, NAXIS %d", naxis);
    int y, mo, da, h, mi;
    double sec;
    CHECK(sscanf(m.date_obs, "%4d-%2d-%2dT%2d:%2d:%lf", &y, &mo, &da, &h, &mi,
                 &sec) == 6 && y >= 2024 && mo >= 1 && mo <= 12,
          "DATE-OBS '%s'", m.date_obs);
}

/* ---- sequences --------------------------------------------------------- */

/* files 0..3 = frame 0 (2-D), frames 1-3 (cube), frame 4, frame 5. */
static int write_split(tmpdir *d, const seq *s, const char **paths)
{
    static const int first[] = {0, 1, 4, 5, 6};
    static const char *names[] = {"s0.fits", "s1.fits", "s2.fits", "s3.fits"};
    int rc = SL_OK;
    for (int f = 0; f < 4 && rc == SL_OK; f++) {
        seq *part = seq_new(s->width, s->height, first[f + 1] - first[f]);
        memcpy(part->data, seq_frame(s, first[f]), seq_frame_pixels(s) *
               (size_t)part->nframes * sizeof(float));
        paths[f] = tmp_path(d, f, names[f]);
        rc = cube_write(paths[f], part, NULL, NULL);
        seq_free(part);
    }
    return rc;
}

TEST(frame_list_is_one_sequence_and_streams)
{
    tmpdir d;
    const char *paths[4];
    seq *s = pattern_seq(9, 7, 6, -50), *got = NULL;
    cube_reader *r = NULL;
    sl_err e = {0};
    float frame[63];
    CHECK(tmp_make(&d), "mkdtemp");
    int rc = write_split(&d, s, paths);
    rc = rc ? rc : cube_read(&got, NULL, paths, 4, 0, &e);
    int same = rc == SL_OK && seq_equal(s, got);
    rc = rc ? rc : cube_reader_open(&r, paths, 4, 0, &e);
    CHECK(rc == SL_OK && same, "rc %d %s", rc, e.msg);
    CHECK(cube_reader_width(r) == 9 && cube_reader_height(r) == 7 &&
          cube_reader_nframes(r) == 6, "sizes");
    for (int pass = 0; pass < 2; pass++) {
        for (int k = 0; k < 6 - 3 * pass && rc == SL_OK; k++) {
            rc = cube_reader_next(r, frame);
            CHECK(rc == SL_OK && !memcmp(frame, seq_frame(s, k), sizeof frame),
                  "pass %d frame %d: %s", pass, k, cube_reader_errmsg(r));
        }
        if (pass == 0)
            CHECK(cube_reader_next(r, frame) == SL_EEND, "end");
        cube_reader_rewind(r);
    }
    cube_reader_free(r);
    seq_free(s);
    seq_free(got);
    tmp_remove(&d);
}

/* Seeking forwards, backwards and within a file of a four-file sequence
 * gives each frame; a copy (cube_reader_dup) reads on its own, before
 * and after the original is freed. */
TEST(seek_any_order_and_dup)
{
    tmpdir d;
    const char *paths[4];
    seq *s = pattern_seq(9, 7, 6, -50);
    cube_reader *r = NULL, *c = NULL;
    sl_err e = {0};
    float frame[63];
    CHECK(tmp_make(&d), "mkdtemp");
    int rc = write_split(&d, s, paths);
    rc = rc ? rc : cube_reader_open(&r, paths, 4, 0, &e);
    rc = rc ? rc : cube_reader_dup(&c, r, &e);
    CHECK(rc == SL_OK, "rc %d %s", rc, e.msg);
    static const int order[] = {5, 0, 3, 3, 1, 4, 2, 5};
    for (int i = 0; i < 8 && rc == SL_OK; i++) {
        rc = cube_reader_seek(c, order[i]);
        rc = rc ? rc : cube_reader_next(c, frame);
        CHECK(rc == SL_OK && !memcmp(frame, seq_frame(s, order[i]), sizeof frame),
              "copy, seek %d: rc %d %s", order[i], rc, cube_reader_errmsg(c));
        if (i == 3) {
            CHECK(cube_reader_next(r, frame) == SL_OK &&
                  !memcmp(frame, seq_frame(s, 0), sizeof frame), "the original's frame 0");
            cube_reader_free(r);
            r = NULL;
        }
    }
    CHECK(cube_reader_next(c, frame) == SL_EEND, "the copy's end after frame 5");
    cube_reader_free(c);
    seq_free(s);
    tmp_remove(&d);
}

TEST(glob_expands_in_strcmp_order)
{
    static const char *names[] = {"g_10.fits", "g_b.fits", "g_01.fits",
                                  "g_02.fits"};
    static const float rank[] = {2, 3, 0, 1}; /* sorted position */
    tmpdir d;
    seq *one = seq_new(2, 2, 1), *got = NULL;
    sl_err e = {0};
    CHECK(tmp_make(&d), "mkdtemp");
    for (int i = 0; i < 4; i++) {
        for (int j = 0; j < 4; j++)
            one->data[j] = rank[i];
        cube_write(tmp_path(&d, 0, names[i]), one, NULL, NULL);
    }
    const char *pat = tmp_path(&d, 1, "g_*.fits");
    const char *none = tmp_path(&d, 2, "zz*.fits");
    int rc = cube_read(&got, NULL, &pat, 1, 0, &e);
    int ok = rc == SL_OK && got->nframes == 4;
    for (int k = 0; ok && k < 4; k++)
        ok = seq_frame(got, k)[3] == (float)k;
    seq_free(got);
    seq_free(one);
    CHECK(ok, "rc %d %s", rc, e.msg);
    rc = cube_read(&got, NULL, &none, 1, 0, &e);
    tmp_remove(&d);
    CHECK(rc == SL_EIO && strstr(e.msg, "zz*.fits"), "%d %s", rc, e.msg);
}

TEST(flushed_frames_survive_a_crash)
{
    tmpdir d;
    seq *s = pattern_seq(33, 17, 5, 1000), *got = NULL;
    sl_err e = {0};
    CHECK(tmp_make(&d), "mkdtemp");
    const char *p = tmp_path(&d, 0, "crash.fits");
    fflush(stdout);
    pid_t pid = fork();
    CHECK(pid >= 0, "fork");
    if (pid == 0) { /* the "daemon": flush, then die (SIGKILL) unclosed */
        cube_writer *w = NULL;
        int rc = cube_writer_open(&w, p, 33, 17, CUBE_BITPIX_U16, NULL, NULL);
        for (int k = 0; rc == SL_OK && k < 5; k++) {
            rc = cube_writer_append(w, seq_frame(s, k));
            if (rc == SL_OK && (k == 2 || k == 4))
                rc = cube_writer_flush(w);
        }
        if (rc != SL_OK)
            _exit(1);
        raise(SIGKILL);   /* a real crash: no atexit, no leak report */
    }
    int status = 0;
    waitpid(pid, &status, 0);
    int rc = cube_read(&got, NULL, &p, 1, 0, &e);
    int same = rc == SL_OK && seq_equal(s, got);
    seq_free(s);
    seq_free(got);
    tmp_remove(&d);
    CHECK(WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL, "child failed (status %#x)", status);
    CHECK(same, "rc %d: %s", rc, e.msg);
}

TEST(write_errors_are_reported)
{
    tmpdir d;
    CHECK(tmp_make(&d), "mkdtemp");
    const char *p = tmp_path(&d, 0, "full.fits");
    fflush(stdout);
    pid_t pid = fork();
    CHECK(pid >= 0, "fork");
    if (pid == 0) { /* a 20 kB file-size limit plays the full disk */
        struct rlimit rl = {20000, 20000};
        static float frame[64 * 64];
        cube_writer *w = NULL;
        signal(SIGXFSZ, SIG_IGN);
        setrlimit(RLIMIT_FSIZE, &rl);
        int rc = cube_writer_open(&w, p, 64, 64, -32, NULL, NULL);
        for (int k = 0; rc == SL_OK && k < 4; k++)
            rc = cube_writer_append(w, frame);
        int rc_close = cube_writer_close(w);
        int named = strstr(cube_writer_errmsg(w), p) != NULL;
        cube_writer_free(w);
        _exit((rc != SL_OK || rc_close != SL_OK) && named ? 0 : 1);
    }
    int status = 0;
    waitpid(pid, &status, 0);
    tmp_remove(&d);
    CHECK(WIFEXITED(status) && WEXITSTATUS(status) == 0,
          "a write past the size limit went unreported");
}

TEST(image_extensions)
{
    tmpdir d;
    seq *s = pattern_seq(6, 4, 3, 0), *truth = pattern_seq(5, 5, 1, 7);
    seq *got = NULL, *x = NULL;
    cube_writer *w = NULL;
    cube_meta m;
    sl_err e = {0};
    CHECK(tmp_make(&d), "mkdtemp");
    const char *p = tmp_path(&d, 0, "ext.fits");
    cube_meta_init(&m);
    cube_meta_set_num(&m, "SEP_PX", 3.5, NULL);
    int rc = cube_writer_open(&w, p, 6, 4, -32, NULL, &e);
    for (int k = 0; rc == SL_OK && k < 3; k++)
        rc = cube_writer_append(w, seq_frame(s, k));
    rc = rc ? rc : cube_writer_add_image(w, "TRUTH", truth->data, 5, 5, &m);
    rc = rc ? rc : cube_writer_add_image(w, "COPHASED", s->data, 6, 4, NULL);
    int rc_late = w ? cube_writer_append(w, s->data) : SL_OK;
    rc = rc ? rc : cube_writer_close(w);
    cube_writer_free(w);
    CHECK(rc == SL_OK && rc_late == SL_EINVAL, "rc %d late %d", rc, rc_late);
    rc = cube_read(&got, NULL, &p, 1, 0, &e);
    int ok = rc == SL_OK && seq_equal(s, got);
    seq_free(got);
    rc = rc ? rc : cube_read_ext(&x, p, "TRUTH", &e);
    ok = ok && rc == SL_OK && seq_equal(x, truth);
    seq_free(x);
    rc = rc ? rc : cube_read_ext(&x, p, "COPHASED", &e);
    ok = ok && rc == SL_OK && !memcmp(x->data, s->data, 24 * sizeof(float));
    seq_free(x);
    int rc_none = cube_read_ext(&x, p, "NOSUCH", &e);
    seq_free(s);
    seq_free(truth);
    tmp_remove(&d);
    CHECK(ok, "%s", e.msg);
    CHECK(rc_none == SL_EFORMAT && strstr(e.msg, "NOSUCH"), "%s", e.msg);
}

/* ---- errors ------------------------------------------------------------ */

/* Files that are not a readable image, each with its status and words. */
static int make_bad(const char *path, int kind)
{
    long one[1] = {10}, four[4] = {2, 2, 2, 2};
    FILE *f = kind == 1 || kind == 2 ? fopen(path, "w") : NULL;
    if (f && kind == 1)
        fputs("this is a text file, not FITS\n", f);
    if (f)
        fclose(f);
    return kind == 3 ? raw_image(path, -32, 1, one)
         : kind == 4 ? raw_image(path, 16, 4, four) : 0;
}

TEST(unreadable_files)
{
    static const struct {
        int rc;
        const char *words;
    } want[] = {{SL_EIO, "No such file"}, {SL_EFORMAT, "not a FITS file"},
                {SL_EFORMAT, "0 bytes"}, {SL_EFORMAT, "NAXIS = 1"},
                {SL_EFORMAT, "NAXIS = 4"}};
    tmpdir d;
    seq *s = NULL;
    sl_err e = {0};
    CHECK(tmp_make(&d), "mkdtemp");
    for (int k = 0; k < 5; k++) {
        const char *p = tmp_path(&d, 0, "bad.fits");
        unlink(p);
        CHECK(make_bad(p, k) == 0, "setup %d", k);
        int rc = cube_read(&s, NULL, &p, 1, 0, &e);
        CHECK(rc == want[k].rc && strstr(e.msg, p) &&
              strstr(e.msg, want[k].words) && !s, "case %d: %d %s", k, rc,
              e.msg);
    }
    tmp_remove(&d);
}

TEST(frame_list_with_mismatched_sizes)
{
    tmpdir d;
    seq *s = NULL;
    sl_err e = {0};
    long a[2] = {8, 8}, b[2] = {8, 9};
    CHECK(tmp_make(&d), "mkdtemp");
    const char *list[3] = {tmp_path(&d, 0, "a.fits"), tmp_path(&d, 1, "b.fits"),
                           tmp_path(&d, 2, "c.fits")};
    raw_image(list[0], -32, 2, a);
    raw_image(list[1], -32, 2, a);
    raw_image(list[2], -32, 2, b);
    int rc = cube_read(&s, NULL, list, 3, 0, &e);
    tmp_remove(&d);
    CHECK(rc == SL_EFORMAT && strncmp(e.msg, list[2], strlen(list[2])) == 0 &&
          strstr(e.msg, "8 x 9"), "%s", e.msg);
}

/* Header cards that are not FITS text (a byte outside ASCII 32-126, a
 * value after a bare "=") are refused before cfitsio parses them: cfitsio
 * 4.2 aborts on a 71-byte column name after a bare "=" (found by
 * fuzz_fits_list).  The untouched file reads. */
static int patch_header(const char *path, int k)
{
    seq *s = pattern_seq(8, 8, 2, 0);
    int rc = cube_write(path, s, NULL, NULL);
    seq_free(s);
    FILE *f = rc == SL_OK ? fopen(path, "r+b") : NULL;
    char hdr[2880];
    if (!f || fread(hdr, 1, sizeof hdr, f) != sizeof hdr) {
        if (f)
            fclose(f);
        return -1;
    }
    int end = 0;
    while (end < 36 && strncmp(hdr + 80 * end, "END     ", 8))
        end++;
    if (k == 1)
        hdr[80 + 75] = (char)0xe8;   /* in BITPIX's comment */
    if (k == 2 && end < 35) {        /* a card "JUNK    =1", then END */
        memcpy(hdr + 80 * (end + 1), hdr + 80 * end, 80);
        memset(hdr + 80 * end, ' ', 80);
        memcpy(hdr + 80 * end, "JUNK    =1", 10);
    }
    rc = fseek(f, 0, SEEK_SET) || fwrite(hdr, 1, sizeof hdr, f) != sizeof hdr;
    return fclose(f) || rc || (k == 2 && end >= 35) ? -1 : 0;
}

TEST(header_text_is_checked)
{
    tmpdir d;
    seq *s = NULL;
    sl_err e = {0};
    CHECK(tmp_make(&d), "mkdtemp");
    const char *p = tmp_path(&d, 0, "hdr.fits");
    for (int k = 0; k < 3; k++) {
        CHECK(patch_header(p, k) == 0, "setup %d", k);
        int rc = cube_read(&s, NULL, &p, 1, 0, &e);
        if (k == 0)
            CHECK(rc == SL_OK && s, "untouched: %s", e.msg);
        else
            CHECK(rc == SL_EFORMAT && strstr(e.msg, p) && strstr(e.msg, "not FITS text") &&
                      !s, "case %d: %d %s", k, rc, e.msg);
        seq_free(s);
        s = NULL;
    }
    tmp_remove(&d);
}

/* Write a cube of 64x64 frames (16 kB each: cfitsio reads them directly,
 * bypassing its 2880-byte buffers) and cut it at byte `keep`. */
static int truncated_cube(const char *path, off_t keep)
{
    seq *s = pattern_seq(64, 64, 4, 0);
    int rc = cube_write(path, s, NULL, NULL);
    seq_free(s);
    return rc == SL_OK ? truncate(path, keep) : -1;
}

TEST(truncated_files)
{
    static const off_t cuts[] = {2880 + 2 * 16384 + 100, 2880 + 16384 * 3,
                                 2880 + 4 * 16384 - 4, 1000};
    tmpdir d;
    seq *s = NULL;
    sl_err e = {0};
    CHECK(tmp_make(&d), "mkdtemp");
    const char *p = tmp_path(&d, 0, "cut.fits");
    for (size_t i = 0; i < sizeof cuts / sizeof cuts[0]; i++) {
        CHECK(truncated_cube(p, cuts[i]) == 0, "setup");
        int rc = cube_read(&s, NULL, &p, 1, 0, &e);
        CHECK(rc == SL_EFORMAT && strstr(e.msg, p) &&
              strstr(e.msg, "truncated") && !s, "cut at %lld: %d %s",
              (long long)cuts[i], rc, e.msg);
    }
    tmp_remove(&d);
}

TEST(nonfinite_pixels)
{
    tmpdir d;
    seq *s = pattern_seq(6, 5, 3, 0), *got = NULL;
    cube_reader *r = NULL;
    sl_err e = {0};
    float frame[30];
    CHECK(tmp_make(&d), "mkdtemp");
    const char *p = tmp_path(&d, 0, "nan.fits");
    seq_frame(s, 1)[3 * 6 + 2] = NAN;
    seq_frame(s, 1)[4 * 6 + 4] = INFINITY;
    seq_frame(s, 2)[0] = -INFINITY;
    int rc = cube_write(p, s, NULL, &e);
    CHECK(rc == SL_OK, "%s", e.msg);
    rc = cube_read(&got, NULL, &p, 1, 0, &e);
    CHECK(rc == SL_EDATA && strstr(e.msg, p) && strstr(e.msg, "2 non-finite")
          && strstr(e.msg, "(2, 3, 1)"), "%d %s", rc, e.msg);
    rc = cube_reader_open(&r, &p, 1, 0, &e);
    int r0 = rc ? rc : cube_reader_next(r, frame);
    int r1 = rc ? rc : cube_reader_next(r, frame);
    int r2 = rc ? rc : cube_reader_next(r, frame); /* bad frames skipped */
    int r3 = rc ? rc : cube_reader_next(r, frame);
    cube_reader_free(r);
    CHECK(r0 == SL_OK && r1 == SL_EDATA && r2 == SL_EDATA && r3 == SL_EEND,
          "streaming %d %d %d %d", r0, r1, r2, r3);
    rc = cube_read(&got, NULL, &p, 1, CUBE_ALLOW_NONFINITE, &e);
    int same = rc == SL_OK && isnan(seq_frame(got, 1)[20]) &&
               seq_frame(got, 1)[28] == INFINITY &&
               seq_frame(got, 2)[0] == -INFINITY &&
               seq_frame(got, 2)[1] == seq_frame(s, 2)[1];
    seq_free(s);
    seq_free(got);
    tmp_remove(&d);
    CHECK(same, "passed through: %s", e.msg);
}

/* ---- the real A 258 frames --------------------------------------------- */

#define A258_DIR "../shared/data/a258"

/* Decode one BITPIX 16 file by hand: find END in the 80-byte cards, data
 * starts at the next 2880-byte block, big-endian int16 plus BZERO. */
static float *raw_decode(const char *path, int *w, int *h, double *bzero)
{
    FILE *f = fopen(path, "rb");
    char card[81] = {0};
    long ncards = 0;
    int bitpix = 0, end = 0;
    *w = *h = 0;
    *bzero = 0;
    while (f && !end && fread(card, 1, 80, f) == 80) {
        ncards++;
        sscanf(card, "BITPIX  = %d", &bitpix);
        sscanf(card, "NAXIS1  = %d", w);
        sscanf(card, "NAXIS2  = %d", h);
        sscanf(card, "BZERO   = %lf", bzero);
        end = strncmp(card, "END     ", 8) == 0;
    }
    float *img = NULL;
    size_t n = (size_t)*w * (size_t)*h;
    if (end && bitpix == 16 && n > 0 && (img = malloc(n * sizeof *img)) &&
        fseek(f, (ncards * 80 + 2879) / 2880 * 2880, SEEK_SET) == 0) {
        for (size_t i = 0; i < n; i++) {
            unsigned char b[2] = {0, 0};
            if (fread(b, 1, 2, f) != 2)
                img[i] = NAN;
            else
                img[i] = (float)((int16_t)(uint16_t)((b[0] << 8) | b[1]) +
                                 *bzero);
        }
    }
    if (f)
        fclose(f);
    return img;
}

TEST(real_a258_frames)
{
    if (access(A258_DIR, F_OK) != 0)
        SKIP("%s is absent (tests run from the repo root)", A258_DIR);
    const char *pat = A258_DIR "/a258_f*.fit";
    seq *s = NULL;
    cube_meta m;
    sl_err e = {0};
    int rc = cube_read(&s, &m, &pat, 1, 0, &e);
    CHECK(rc == SL_OK, "%s", e.msg);
    int dims_ok = s->nframes == 12 && s->width == 192 && s->height == 192;
    int w = 0, h = 0;
    double bzero = 0;
    float *raw = raw_decode(A258_DIR "/a258_f0006.fit", &w, &h, &bzero);
    int same = raw && dims_ok && w == 192 && h == 192 &&
               !memcmp(raw, seq_frame(s, 5), sizeof(float) * 192 * 192);
    float lo = 1e30f, hi = -1e30f;
    for (size_t i = 0; raw && i < 192 * 192; i++) {
        lo = raw[i] < lo ? raw[i] : lo;
        hi = raw[i] > hi ? raw[i] : hi;
    }
    free(raw);
    int nf = s->nframes, sw = s->width, sh = s->height;
    seq_free(s);
    CHECK(dims_ok, "%d frames of %d x %d", nf, sw, sh);
    CHECK(bzero == 32768.0 && same, "frame 5 differs from the raw bytes "
          "(BZERO %g)", bzero);
    CHECK(lo >= 0.0f && hi <= 65535.0f, "unsigned range [%g, %g]", lo, hi);
    CHECK(!strncmp(m.date_obs, "2023-09-07T", 11), "DATE-OBS %s", m.date_obs);
}

TC_MAIN(TC_CASE(every_bitpix_round_trips_exactly),
        TC_CASE(integer_types_round_and_refuse_out_of_range),
        TC_CASE(metadata_and_extras_round_trip),
        TC_CASE(meta_setters_validate_keys),
        TC_CASE(foreign_keywords_and_extension_data),
        TC_CASE(default_date_and_naxis),
        TC_CASE(frame_list_is_one_sequence_and_streams), TC_CASE(seek_any_order_and_dup),
        TC_CASE(glob_expands_in_strcmp_order),
        TC_CASE(flushed_frames_survive_a_crash), TC_CASE(header_text_is_checked),
        TC_CASE(write_errors_are_reported),
        TC_CASE(image_extensions),
        TC_CASE(unreadable_files),
        TC_CASE(frame_list_with_mismatched_sizes),
        TC_CASE(extras_beyond_the_bound_are_counted),
        TC_CASE(truncated_files),
        TC_CASE(nonfinite_pixels),
        TC_CASE(real_a258_frames))
