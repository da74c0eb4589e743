/* test_pipeline_opts.c - pipeline_opts_set (recon/pipeline/pipeline_optset.c),
 * through which the CLI reads its command line and specklabd a client's
 * options: every name it lists takes a value and changes what it names
 * (and nothing else), flags take "", true and false, bad values and
 * unknown names are refused naming the option, and nothing is changed by
 * a refusal.
 */
#include <string.h>

#include "pipeline/pipeline.h"
#include "tcheck.h"

/* A value each option takes that differs from its default. */
static const char *value_for(const char *name)
{
    static const struct { const char *name, *value; } v[] = {
        {"method", "direct"}, {"skips", "crop"}, {"target-error", "0.05"},
        {"projections", "90"}, {"r2-px", "20"}, {"bispec-memory-mb", "256"},
        {"wiener", "0.01"}, {"photons", "1e4"},
        {"adu-per-photon", "2"}, {"tsm-inverse", "iter"}, {"tsm-phases", "corrected"},
        {"window", "hann"}, {"saturation-adu", "4095"}, {"threads", "2"},
        {"phase-weights", "unit"}, {"refine", "5"}};
    for (size_t i = 0; i < sizeof v / sizeof v[0]; i++)
        if (!strcmp(v[i].name, name))
            return v[i].value;
    return NULL;
}

/* How many bytes of two option sets differ. */
static int ndiff(const pipeline_opts *a, const pipeline_opts *b)
{
    const unsigned char *p = (const void *)a, *q = (const void *)b;
    int n = 0;
    for (size_t i = 0; i < sizeof *a; i++)
        n += p[i] != q[i];
    return n;
}

TEST(every_option_sets_what_it_names)
{
    int is_flag, n = 0;
    const char *name;
    for (int i = 0; (name = pipeline_opts_name(i, &is_flag)); i++, n++) {
        pipeline_opts d, o;
        pipeline_opts_defaults(&d);
        pipeline_opts_defaults(&o);
        sl_err e = {0};
        const char *v = is_flag ? "" : value_for(name);
        CHECK(v, "no test value for --%s: add one", name);
        CHECK(pipeline_opts_set(&o, name, v, &e) == SL_OK, "--%s %s: %s", name, v, e.msg);
        CHECK(ndiff(&d, &o) > 0, "--%s %s changed nothing", name, v);
        /* a valid set too (the wiener regularises a reference: needs one) */
        CHECK(!strcmp(name, "wiener") || pipeline_opts_check(&o, &e) == SL_OK, "--%s %s: %s",
              name, v, e.msg);
        if (is_flag) {
            pipeline_opts f;
            pipeline_opts_defaults(&f);
            CHECK(pipeline_opts_set(&f, name, "false", &e) == SL_OK && ndiff(&d, &f) == 0,
                  "--%s false changed the defaults", name);
            CHECK(pipeline_opts_set(&f, name, "true", &e) == SL_OK && ndiff(&o, &f) == 0,
                  "--%s true is not --%s", name, name);
        }
    }
    CHECK(n >= 20, "only %d options", n);
}

TEST(fields_land_where_the_cli_puts_them)
{
    pipeline_opts o;
    pipeline_opts_defaults(&o);
    sl_err e = {0};
    CHECK(pipeline_opts_set(&o, "r2-px", "17", &e) == SL_OK && o.r2_px == 17, "r2");
    CHECK(pipeline_opts_set(&o, "projections", "90", &e) == SL_OK && o.nangles == 90, "p");
    CHECK(pipeline_opts_set(&o, "no-prep", "", &e) == SL_OK && o.prep == 0, "no-prep");
    CHECK(pipeline_opts_set(&o, "binary", "true", &e) == SL_OK && o.closure_binary == 1, "bin");
    CHECK(pipeline_opts_set(&o, "skips", "all", &e) == SL_OK && o.skips == PIPE_SKIP_ALL, "sk");
    CHECK(pipeline_opts_set(&o, "method", "tsm-fourier", &e) == SL_OK &&
          o.method == PIPE_TSM_FOURIER, "method");
    CHECK(pipeline_opts_set(&o, "photons", "-1", &e) == SL_OK && o.photons_per_frame == -1,
          "photons");
}

TEST(refusals_name_the_option_and_change_nothing)
{
    static const struct { const char *name, *value, *says; } bad[] = {
        {"window", "bogus", "unknown --window 'bogus' (none, hann, tukey)"},
        {"method", "fast", "unknown --method 'fast'"},
        {"skips", "crop,x", "--skips 'crop,x'"},
        {"r2-px", "12.5", "--r2-px '12.5': not an integer"},
        {"projections", "", "--projections '': not an integer"},
        {"wiener", "nan", "--wiener 'nan': not a finite number"},
        {"target-error", "0.1x", "--target-error '0.1x'"},
        {"binary", "maybe", "--binary takes no value"},
        {"ref", "x.fits", "unknown option --ref"},
        {"dark", "d.fits", "unknown option --dark"},
    };
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        pipeline_opts d, o;
        pipeline_opts_defaults(&d);
        pipeline_opts_defaults(&o);
        sl_err e = {0};
        int rc = pipeline_opts_set(&o, bad[i].name, bad[i].value, &e);
        CHECK(rc == SL_EINVAL && strstr(e.msg, bad[i].says), "--%s '%s': %d '%s'",
              bad[i].name, bad[i].value, rc, e.msg);
        CHECK(ndiff(&d, &o) == 0, "--%s '%s' was refused but changed the options",
              bad[i].name, bad[i].value);
    }
}

TC_MAIN(TC_CASE(every_option_sets_what_it_names), TC_CASE(fields_land_where_the_cli_puts_them),
        TC_CASE(refusals_name_the_option_and_change_nothing))
