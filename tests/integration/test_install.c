/* test_install.c - make install / uninstall into a staging root, as a
 * packager runs them: the programs are installed (specklab-mpi too when
 * the build has MPI), specklab and specklabd run and say their version,
 * the three man pages render, the unit passes systemd-analyze verify, an edited
 * configuration survives a reinstall and an uninstall, and uninstall
 * removes everything else.  make runs from the source tree (the tests'
 * working directory) on the programs already built. */
#define _GNU_SOURCE
#include <libgen.h>
#include <limits.h>
#include <stdlib.h>
#include <sys/stat.h>
#include <unistd.h>

#include "base/version.h"
#include "cli.h"
#include "proc_fx.h"
#include "tcheck.h"

typedef struct inst {
    char root[64];
    char bin[PATH_MAX], build[PATH_MAX];
    char out[8192];
} inst;

/* argv run with env additions (NULL-terminated "K=V"), MAKEFLAGS and the
 * like removed so a nested make does not join the test's; exit status,
 * stdout + stderr in in->out. */
static int run(inst *in, char **argv, const char *const *env)
{
    char **e = g_get_environ();
    const char *drop[] = {"MAKEFLAGS", "MFLAGS", "MAKELEVEL", "MAKEOVERRIDES"};
    for (size_t i = 0; i < G_N_ELEMENTS(drop); i++)
        e = g_environ_unsetenv(e, drop[i]);
    for (int i = 0; env && env[i]; i++) {
        char *k = g_strndup(env[i], strcspn(env[i], "="));
        e = g_environ_setenv(e, k, env[i] + strlen(k) + 1, TRUE);
        g_free(k);
    }
    char *so = NULL, *se = NULL;
    int st = -1;
    gboolean ok = g_spawn_sync(NULL, argv, e, G_SPAWN_SEARCH_PATH, NULL, NULL, &so, &se,
                               &st, NULL);
    snprintf(in->out, sizeof in->out, "%s%s", so ? so : "", se ? se : "");
    g_free(so);
    g_free(se);
    g_strfreev(e);
    return ok && WIFEXITED(st) ? WEXITSTATUS(st) : -1;
}

static int inst_start(inst *in)
{
    snprintf(in->root, sizeof in->root, "/tmp/sl_install_XXXXXX");
    if (!mkdtemp(in->root))
        return -1;
    char prog[PATH_MAX], tmp[PATH_MAX];
    fx_bin(prog, sizeof prog, "specklab");
    snprintf(in->bin, sizeof in->bin, "%s", dirname(prog));
    snprintf(tmp, sizeof tmp, "%s", in->bin);
    char *parent = dirname(tmp);
    /* build-asan/bin -> BUILD=build-asan; ./bin -> build */
    snprintf(in->build, sizeof in->build, "%s",
             strncmp(basename(parent), "build", 5) == 0 ? parent : "build");
    return 0;
}

static void inst_stop(inst *in)
{
    char *cmd = g_strdup_printf("rm -rf '%s'", in->root);
    if (system(cmd) != 0)
        fprintf(stderr, "could not remove %s\n", in->root);
    g_free(cmd);
}

/* make TARGET DESTDIR=dest PREFIX=prefix on the built programs. */
static int make(inst *in, const char *target, const char *dest, const char *prefix)
{
    char d[PATH_MAX + 8], p[PATH_MAX + 8], b[PATH_MAX + 8], u[PATH_MAX + 8];
    snprintf(d, sizeof d, "DESTDIR=%s", dest);
    snprintf(p, sizeof p, "PREFIX=%s", prefix);
    snprintf(b, sizeof b, "BIN=%s", in->bin);
    snprintf(u, sizeof u, "BUILD=%s", in->build);
    char *argv[] = {"make", "-s", (char *)target, d, p, b, u, NULL};
    return run(in, argv, NULL);
}

static int exists(const char *root, const char *rel)
{
    char *p = g_strdup_printf("%s%s", root, rel);
    int ok = access(p, F_OK) == 0;
    g_free(p);
    return ok;
}

#ifndef SL_HAVE_MPI
#define SL_HAVE_MPI 0
#endif

static const char *const installed[] = {
#if SL_HAVE_MPI
    "/usr/bin/specklab-mpi",   /* with MPI; before the configuration, kept last */
#endif
    "/usr/bin/specklab", "/usr/sbin/specklabd", "/usr/share/man/man1/specklab.1",
    "/usr/share/man/man8/specklabd.8", "/usr/share/man/man5/specklabd.conf.5",
    "/usr/lib/systemd/system/specklabd.service", "/usr/share/doc/specklab/PROTOCOL.md",
    "/etc/specklab/specklabd.conf"};

TEST(install_run_render_uninstall)
{
    inst in;
    CHECK(inst_start(&in) == 0, "mkdtemp");
    char dest[PATH_MAX];
    snprintf(dest, sizeof dest, "%s/stage", in.root);
    int rc = make(&in, "install", dest, "/usr");
    char why[512] = "";
    if (rc != 0)
        snprintf(why, sizeof why, "make install: %d: %.400s", rc, in.out);
    for (size_t i = 0; !why[0] && i < G_N_ELEMENTS(installed); i++)
        if (!exists(dest, installed[i]))
            snprintf(why, sizeof why, "%s not installed", installed[i]);
    char prog[PATH_MAX + 32], want[64];
    const char *names[] = {"/usr/bin/specklab", "/usr/sbin/specklabd"};
    for (int i = 0; !why[0] && i < 2; i++) {
        snprintf(prog, sizeof prog, "%s%s", dest, names[i]);
        snprintf(want, sizeof want, "%s %s\n", basename(prog), SPECKLAB_VERSION);
        char *argv[] = {prog, "--version", NULL};
        if (run(&in, argv, NULL) != 0 || strcmp(in.out, want) != 0)
            snprintf(why, sizeof why, "%s --version said '%.100s'", names[i], in.out);
    }
    const char *pages[][2] = {{"/usr/share/man/man1/specklab.1", "recon"},
                              {"/usr/share/man/man8/specklabd.8", "systemd"},
                              {"/usr/share/man/man5/specklabd.conf.5", "data_dir"}};
    const char *nopager[] = {"MANPAGER=cat", "PAGER=cat", "MANWIDTH=80", NULL};
    for (int i = 0; !why[0] && i < 3; i++) {
        char *page = g_strdup_printf("%s%s", dest, pages[i][0]);
        char *argv[] = {"man", "-l", page, NULL};
        int mrc = run(&in, argv, nopager);
        if (mrc != 0 || !strstr(in.out, "NAME") || !strstr(in.out, pages[i][1]))
            snprintf(why, sizeof why, "man -l %s: %d: %.200s", pages[i][0], mrc, in.out);
        g_free(page);
    }
    /* an edited configuration survives a reinstall and the uninstall */
    char *conf = g_strdup_printf("%s/etc/specklab/specklabd.conf", dest);
    int edited = !why[0] && g_file_set_contents(conf, "# ours\n", -1, NULL) &&
                 make(&in, "install", dest, "/usr") == 0;
    int urc = !why[0] ? make(&in, "uninstall", dest, "/usr") : -1;
    int left = 0;
    for (size_t i = 0; i + 1 < G_N_ELEMENTS(installed); i++)
        left += exists(dest, installed[i]);
    char *kept = NULL;
    g_file_get_contents(conf, &kept, NULL, NULL);
    int conf_kept = kept && !strcmp(kept, "# ours\n");
    g_free(kept);
    g_free(conf);
    inst_stop(&in);
    CHECK(!why[0], "%s", why);
    CHECK(edited && urc == 0, "reinstall %d, uninstall %d: %.300s", edited, urc, in.out);
    CHECK(left == 0, "%d installed files left after uninstall", left);
    CHECK(conf_kept, "the edited configuration was replaced or removed");
}

/* The unit as installed passes systemd-analyze verify: installed under a
 * prefix of its own (no DESTDIR) so that ExecStart names a program that
 * exists, and with MANPATH on its man pages, which the unit's
 * Documentation= names. */
TEST(unit_verifies)
{
    if (access("/usr/bin/systemd-analyze", X_OK) != 0)
        SKIP("systemd-analyze is not installed (Debian: systemd)");
    inst in;
    CHECK(inst_start(&in) == 0, "mkdtemp");
    char prefix[PATH_MAX];
    snprintf(prefix, sizeof prefix, "%s/usr", in.root);
    int rc = make(&in, "install", "", prefix);
    char *unit = g_strdup_printf("%s/lib/systemd/system/specklabd.service", prefix);
    char *manpath = g_strdup_printf("MANPATH=%s/share/man", prefix);
    const char *env[] = {manpath, NULL};
    char *argv[] = {"systemd-analyze", "verify", unit, NULL};
    int vrc = rc == 0 ? run(&in, argv, env) : -1;
    char *text = NULL;
    g_file_get_contents(unit, &text, NULL, NULL);
    int notify = text && strstr(text, "Type=notify") && strstr(text, "SupplementaryGroups=dialout");
    g_free(text);
    g_free(unit);
    g_free(manpath);
    inst_stop(&in);
    CHECK(rc == 0, "make install PREFIX=%s: %.300s", prefix, in.out);
    CHECK(vrc == 0 && !in.out[0], "systemd-analyze verify: %d: %.400s", vrc, in.out);
    CHECK(notify, "the unit is not Type=notify with the dialout group");
}

TC_MAIN(TC_CASE(install_run_render_uninstall), TC_CASE(unit_verifies))
