/* test_devices_u3v.c - `specklab devices` names why a USB3 Vision camera
 * cannot be used well: no permission on its device node (with the udev
 * rule to install), a USB 2 link for a USB 3 camera, a usbfs memory
 * limit too small for the stream; and says nothing is wrong when nothing
 * is.  The camera is bin/specklab-fake-u3v in a umockdev testbed; the
 * command runs under the preload on it, with the testbed's sysfs "speed",
 * /sys/module/usbcore/parameters/usbfs_memory_mb and node modes set by
 * the camera's options.  Each case checks the JSON findings and the text
 * a user reads.
 *
 * Permissions: root opens any file, so that case runs the command as
 * nobody (uid/gid 65534) on a root:root 0664 node, as a default udev
 * setup leaves it; where privileges cannot be dropped it is skipped.
 */
#define _GNU_SOURCE
#include <grp.h>
#include <json-glib/json-glib.h>
#include <sys/stat.h>
#include <sys/wait.h>

#include "preload_fx.h"
#include "proc_fx.h"
#include "tcheck.h"
#include "u3v_fx.h"

#define NOBODY 65534

typedef struct cli_env {
    char *preload;
    int as_nobody;
} cli_env;

static void cli_pre(void *arg)
{
    cli_env *e = arg;
    setenv("LD_PRELOAD", e->preload, 1);
    if (e->as_nobody && (setgroups(0, NULL) != 0 || setgid(NOBODY) != 0 || setuid(NOBODY) != 0))
        _exit(3);
}

/* `specklab devices --no-stage [--json]` on the camera's testbed: its
 * stdout in out, the exit status (3: could not drop to nobody). */
static int run_devices(int json, int as_nobody, char *out, size_t n)
{
    char bin[PATH_MAX];
    char *argv[] = {bin, "devices", "--no-stage", json ? "--json" : NULL, NULL};
    cli_env env = {fx_preload_value(), as_nobody};
    fx_proc p;
    size_t len = 0;
    ssize_t r;
    int st = -1;
    fx_bin(bin, sizeof bin, "specklab");
    if (fx_spawn(&p, argv, NULL, cli_pre, &env) == 0) {
        while (len + 1 < n && (r = read(p.out, out + len, n - 1 - len)) > 0)
            len += (size_t)r;
        waitpid(p.pid, &st, 0);
        close(p.out);
    }
    out[len] = 0;
    g_free(env.preload);
    return WIFEXITED(st) ? WEXITSTATUS(st) : -1;
}

/* The finding of check `check` on the camera (its "device" names the
 * serial): level, text and fix copied out; 0 when there is one. */
typedef struct finding {
    char level[16], text[512], fix[1024];
} finding;

static int find_usb(const char *json, const char *check, finding *f)
{
    JsonParser *p = json_parser_new();
    int found = -1;
    memset(f, 0, sizeof *f);
    if (json_parser_load_from_data(p, json, -1, NULL)) {
        JsonObject *root = json_node_get_object(json_parser_get_root(p));
        JsonArray *usb = root ? json_object_get_array_member(root, "usb") : NULL;
        for (guint i = 0; usb && i < json_array_get_length(usb) && found; i++) {
            JsonObject *o = json_array_get_object_element(usb, i);
            const char *dev = json_object_get_string_member_with_default(o, "device", "");
            const char *chk = json_object_get_string_member_with_default(o, "check", "");
            int system = !strcmp(check, "usbfs_memory");
            if (strcmp(chk, check) || (!system && !strstr(dev, FX_U3V_SERIAL)))
                continue;
            g_strlcpy(f->level, json_object_get_string_member_with_default(o, "level", ""),
                      sizeof f->level);
            g_strlcpy(f->text, json_object_get_string_member_with_default(o, "text", ""),
                      sizeof f->text);
            g_strlcpy(f->fix, json_object_get_string_member_with_default(o, "fix", ""),
                      sizeof f->fix);
            found = 0;
        }
    }
    g_object_unref(p);
    return found;
}

/* nobody may enter the testbed and reach umockdev's ioctl sockets (the
 * preload connects to them on every open of a /dev path); the device
 * node itself keeps its mode. */
static int open_to_nobody(const fx_u3v *u)
{
    char path[PATH_MAX + 128];
    int rc = chown(u->dir, NOBODY, NOBODY);
    snprintf(path, sizeof path, "%s/ioctl%s", u->dir, u->node);
    rc |= chmod(path, 0666);
    snprintf(path, sizeof path, "%s/ioctl/_default", u->dir);
    return rc | chmod(path, 0666);
}

/* What `specklab devices` says about the camera started with extra: its
 * JSON and its text, and how each run exited. */
typedef struct survey {
    int up, prep, rj, rt;      /* camera started, testbed opened to nobody, exits */
    char json[65536], text[65536];
} survey;

static void survey_run(survey *v, const char *const *extra, int as_nobody)
{
    fx_u3v u;
    memset(v, 0, sizeof *v);
    v->rj = v->rt = -1;
    v->up = fx_u3v_start(&u, extra) == 0;
    if (!v->up)
        return;
    v->prep = as_nobody ? open_to_nobody(&u) : 0;
    if (v->prep == 0) {
        v->rj = run_devices(1, as_nobody, v->json, sizeof v->json);
        v->rt = run_devices(0, as_nobody, v->text, sizeof v->text);
    }
    fx_u3v_stop(&u);
}

#define SURVEY(v, extra, as_nobody)                                           \
    do {                                                                      \
        survey_run(v, extra, as_nobody);                                      \
        CHECK((v)->up, "bin/specklab-fake-u3v did not start (run make)");     \
    } while (0)

/* ---- tests --------------------------------------------------------------- */

/* A USB 3 camera on a USB 3 link, a generous usbfs limit, a node anyone
 * may open: listed, and no problem found. */
TEST(devices_all_well)
{
    static survey v;
    const char *x[] = {"--usbfs-memory-mb", "1000", NULL};
    const char *out = v.json, *text = v.text;
    finding sp, ac, fs;
    SURVEY(&v, x, 0);
    CHECK(v.rj == 0 && v.rt == 0, "specklab devices exited %d / %d", v.rj, v.rt);
    CHECK(strstr(out, "\"serial\":\"" FX_U3V_SERIAL "\"") && strstr(out, "USB3Vision"),
          "the camera is not listed: %s", out);
    CHECK(find_usb(out, "speed", &sp) == 0 && !strcmp(sp.level, "ok") && strstr(sp.text, "5000"),
          "speed: [%s] %s", sp.level, sp.text);
    CHECK(find_usb(out, "access", &ac) == 0 && !strcmp(ac.level, "ok"), "access: [%s] %s",
          ac.level, ac.text);
    CHECK(find_usb(out, "usbfs_memory", &fs) == 0 && !strcmp(fs.level, "ok") &&
              strstr(fs.text, "1000 MB"), "usbfs: [%s] %s", fs.level, fs.text);
    CHECK(strstr(text, "0 problems found"), "text output: %s", text);
}

/* The camera negotiated 480 Mbit/s: a warning that names the USB 2 link
 * and how to get a USB 3 one. */
TEST(devices_usb2_link)
{
    static survey v;
    const char *x[] = {"--speed-mbit", "480", "--usbfs-memory-mb", "1000", NULL};
    const char *out = v.json, *text = v.text;
    finding sp;
    SURVEY(&v, x, 0);
    CHECK(v.rj == 0 && v.rt == 0, "specklab devices exited %d / %d", v.rj, v.rt);
    CHECK(find_usb(out, "speed", &sp) == 0 && !strcmp(sp.level, "warn") &&
              strstr(sp.text, "USB 2.0 link (480 Mbit/s)") && strstr(sp.fix, "USB 3 port"),
          "speed: [%s] %s / %s", sp.level, sp.text, sp.fix);
    CHECK(strstr(text, "[warn]") && strstr(text, "USB 2.0 link") && strstr(text, "fix: Plug it "
          "into a USB 3 port") && strstr(text, "1 problem found"), "text output: %s", text);
}

/* usbfs may pin 16 MB (the kernel default): too small; the fix gives the
 * command for now and the setting for good. */
TEST(devices_usbfs_too_small)
{
    static survey v;
    const char *x[] = {"--usbfs-memory-mb", "16", NULL};
    const char *out = v.json, *text = v.text;
    finding fs;
    SURVEY(&v, x, 0);
    CHECK(v.rj == 0 && v.rt == 0, "specklab devices exited %d / %d", v.rj, v.rt);
    CHECK(find_usb(out, "usbfs_memory", &fs) == 0 && !strcmp(fs.level, "warn") &&
              strstr(fs.text, "16 MB") && strstr(fs.fix, "usbfs_memory_mb") &&
              strstr(fs.fix, "update-grub"), "usbfs: [%s] %s / %s", fs.level, fs.text, fs.fix);
    CHECK(strstr(text, "usbfs memory limit is 16 MB") && strstr(text, "1 problem found"),
          "text output: %s", text);
}

/* The node is root:root 0664: the user cannot open it.  The camera is
 * still seen (sysfs is readable), the finding is an error with the udev
 * rule for its vendor and product and the commands to apply it. */
TEST(devices_no_permission)
{
    static survey v;
    const char *x[] = {"--node-mode", "436", "--usbfs-memory-mb", "1000", NULL}; /* 0664 */
    const char *out = v.json, *text = v.text;
    finding ac;
    SURVEY(&v, x, 1);
    if (geteuid() != 0 || v.rj == 3)
        SKIP("cannot run the command as nobody here (root bypasses the node's mode)");
    CHECK(v.prep == 0, "cannot open the testbed to nobody: %s", strerror(errno));
    CHECK(v.rj == 0 && v.rt == 0, "specklab devices exited %d / %d", v.rj, v.rt);
    CHECK(find_usb(out, "access", &ac) == 0 && !strcmp(ac.level, "error") &&
              strstr(ac.text, "no permission to open /dev/bus/usb/"),
          "access: [%s] %s", ac.level, ac.text);
    CHECK(strstr(ac.fix, "SUBSYSTEM==\"usb\", ATTR{idVendor}==\"1ab2\", ATTR{idProduct}==\"0001\"") &&
              strstr(ac.fix, "/etc/udev/rules.d/99-specklab-camera.rules") &&
              strstr(ac.fix, "udevadm control --reload-rules"), "fix: %s", ac.fix);
    CHECK(strstr(text, "[error]") && strstr(text, "fix: Let group plugdev open it") &&
              strstr(text, "1 problem found"), "text output: %s", text);
}

int main(int argc, char **argv)
{
    static const tc_case cases[] = {
        TC_CASE(devices_all_well),
        TC_CASE(devices_usb2_link),
        TC_CASE(devices_usbfs_too_small),
        TC_CASE(devices_no_permission),
    };
    return tc_main(argv[0], argc, argv, cases, (int)(sizeof cases / sizeof cases[0]));
}
