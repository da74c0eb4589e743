/* test_usb.c - drivers/usb under umockdev: no USB hardware, no privileges.
 *
 * How it works: the binary re-executes itself with
 * LD_PRELOAD=libumockdev-preload.so.0 (what umockdev-wrapper does), so
 * that each test can build a UMockdevTestbed in-process.  The testbed
 * redirects /sys and /dev into a temporary directory, fakes udev
 * (enumeration and uevents over an emulated netlink socket), and routes
 * ioctl()s on /dev/bus/usb/BBB/DDD to the "handle-ioctl" signal of a
 * UMockdevIoctlBase: that handler below is the USB mock.  libusb, loaded
 * normally, sees real-looking sysfs devices ("descriptors", "speed",
 * busnum/devnum), opens their device nodes and talks usbfs ioctls to the
 * mock: GET_CAPABILITIES, RESET, and control URBs (SUBMITURB / REAPURB)
 * for string descriptors.  The handler runs on umockdev's own thread,
 * hence the atomics.
 *
 * Permission: root bypasses file modes, so the permission test re-runs
 * this binary as uid/gid 65534 (nobody) against the same testbed, where
 * the device node is root:root 0664 (the usual default): the kernel
 * itself refuses the O_RDWR open() with EACCES, as with a real
 * /dev/bus/usb node.
 */
#include "tcheck.h"
#include "usb.h"

#include <errno.h>
#include <grp.h>
#include <sys/ioctl.h>
#include <linux/usbdevice_fs.h>
#include <poll.h>
#include <signal.h>
#include <stdint.h>
#include <stdlib.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <umockdev.h>
#include <unistd.h>

#include "usb_mock.h"

/* ---- diagnosis reports ---- */

typedef struct item {
    int has_dev;
    usb_dev_info dev;
    usb_finding f;
} item;

typedef struct report {
    int n;
    item it[16];
} report;

static void collect(const usb_dev_info *d, const usb_finding *f, void *ud)
{
    report *r = ud;
    if (r->n >= (int)(sizeof r->it / sizeof r->it[0]))
        return;
    r->it[r->n].has_dev = d != NULL;
    if (d)
        r->it[r->n].dev = *d;
    r->it[r->n].f = *f;
    r->n++;
}

/* The finding of check c about the device with vid (0: system-wide). */
static const item *finding_of(const report *r, usb_check c, uint16_t vid)
{
    for (int i = 0; i < r->n; i++)
        if (r->it[i].f.check == c &&
            (vid ? r->it[i].has_dev && r->it[i].dev.vid == vid
                 : !r->it[i].has_dev))
            return &r->it[i];
    return NULL;
}

/* ---- hot-plug event log ---- */

typedef struct evlog {
    int n;
    struct {
        usb_event_kind kind;
        usb_dev_info d;
    } e[16];
} evlog;

static void log_event(usb_event_kind kind, const usb_dev_info *d, void *ud)
{
    evlog *l = ud;
    if (l->n < (int)(sizeof l->e / sizeof l->e[0])) {
        l->e[l->n].kind = kind;
        l->e[l->n].d = *d;
        l->n++;
    }
}

static int count_events(const evlog *l, usb_event_kind kind, uint16_t vid)
{
    int k = 0;
    for (int i = 0; i < l->n; i++)
        k += l->e[i].kind == kind && l->e[i].d.vid == vid;
    return k;
}

/* Pump events until kind/vid has been delivered, at most 5 s. */
static int wait_event(usb *u, const evlog *l, usb_event_kind kind, uint16_t vid)
{
    double end = now_s() + 5.0;
    while (count_events(l, kind, vid) == 0 && now_s() < end)
        if (usb_poll(u, 100) != SL_OK)
            return 0;
    return count_events(l, kind, vid) > 0;
}

/* ---- tests ---- */

TEST(enumerate_identifies_u3v)
{
    mock m;
    usb *u;
    usb_dev_info d[8], one[1];
    int n = -1, n_small = -1;
    char label[256];
    SETUP(&m, &u, &CAM, &WEBCAM, &DISK);
    int r = usb_list(u, d, 8, &n);
    int r_small = usb_list(u, one, 1, &n_small);
    teardown(&m, u);
    const usb_dev_info *cam = find(d, n, CAM.vid);
    const usb_dev_info *web = find(d, n, WEBCAM.vid);
    const usb_dev_info *disk = find(d, n, DISK.vid);
    CHECK(r == SL_OK && n == 3 && cam && web && disk, "listed %d devices", n);
    usb_dev_label(cam, label, sizeof label);
    CHECK(cam->is_u3v && cam->u3v_ifaces == 7u && cam->bus == 2 &&
              cam->address == 3 && cam->n_ports == 1 &&
              cam->port_path[0] == 1 &&
              cam->pid == CAM.pid && cam->bcd_usb == 0x0300 &&
              cam->speed == USB_SPEED_SUPER && cam->link_mbit_per_s == 5000 &&
              strcmp(cam->product, "SpeckCam U3") == 0 &&
              strcmp(cam->manufacturer, "Specklab") == 0 &&
              strcmp(cam->serial, "SC0042") == 0,
          "camera misread: %s u3v=%d ifaces=%u speed=%d", label, cam->is_u3v,
          cam->u3v_ifaces, cam->speed);
    /* The webcam has the device class of a U3V camera (0xEF, IAD): only
     * its interfaces (video, 0x0E) tell it apart. */
    CHECK(!web->is_u3v && web->u3v_ifaces == 0 && web->dev_class == 0xEF &&
              web->speed == USB_SPEED_HIGH && !disk->is_u3v &&
              disk->dev_class == 0,
          "a non-camera device was taken for a U3V camera");
    CHECK(strcmp(label, "SpeckCam U3 (1ab2:0001, serial SC0042) on bus 2 "
                 "port 1") == 0, "label \"%s\"", label);
    CHECK(r_small == SL_OK && n_small == 3, "short list: %d devices", n_small);
}

/* A USB3 camera on a USB 2.0 link gets the warning, one on a 5 Gbit/s
 * link does not; non-cameras only appear with USB_DIAG_ALL_DEVICES. */
TEST(link_speed)
{
    mock m;
    usb *u;
    fake_dev slow = CAM;
    slow.speed_mbit = 480;
    SETUP(&m, &u, &slow, &CAM2, &WEBCAM);
    report *cams = g_new0(report, 1), *all = g_new0(report, 1);
    int r1 = usb_diagnose(u, 0, collect, cams);
    int r2 = usb_diagnose(u, USB_DIAG_ALL_DEVICES, collect, all);
    teardown(&m, u);
    const item *sp = finding_of(cams, USB_CHECK_SPEED, CAM.vid);
    const item *ok = finding_of(cams, USB_CHECK_SPEED, CAM2.vid);
    const item *ac = finding_of(cams, USB_CHECK_ACCESS, CAM.vid);
    const item *web = finding_of(all, USB_CHECK_SPEED, WEBCAM.vid);
    item spi = sp ? *sp : (item){0}, oki = ok ? *ok : (item){0};
    int n_cams = cams->n, web_in_cams = !!finding_of(cams, USB_CHECK_SPEED,
                                                     WEBCAM.vid);
    int ac_ok = ac && ac->f.level == USB_LEVEL_OK &&
                strstr(ac->f.text, "can open /dev/bus/usb/002/003");
    int web_ok = web && web->f.level == USB_LEVEL_OK;
    g_free(cams);
    g_free(all);
    CHECK(r1 == SL_OK && r2 == SL_OK, "usb_diagnose failed");
    /* usbfs + (speed, access) per camera; the webcam is not a camera. */
    CHECK(n_cams == 5 && !web_in_cams, "%d findings without ALL", n_cams);
    CHECK(sp && spi.f.level == USB_LEVEL_WARN, "no speed warning");
    CHECK(strstr(spi.f.text, "camera SpeckCam U3 (1ab2:0001, serial SC0042) "
                 "on bus 2 port 1 is on a USB 2.0 link (480 Mbit/s): use a "
                 "USB3 port/cable") != NULL, "text: %s", spi.f.text);
    CHECK(strstr(spi.f.fix, "USB 3") != NULL, "fix: %s", spi.f.fix);
    CHECK(ok && oki.f.level == USB_LEVEL_OK && oki.f.fix[0] == '\0' &&
              strstr(oki.f.text, "5000 Mbit/s link"),
          "super-speed camera: level %d: %s", (int)oki.f.level, oki.f.text);
    CHECK(ac_ok, "root could not open the mock camera");
    CHECK(web_ok, "a USB 2.0 webcam on a USB 2.0 link is fine");
}

static int write_text(const char *path, const char *text)
{
    char *dir = g_path_get_dirname(path);
    int r = g_mkdir_with_parents(dir, 0755);
    g_free(dir);
    return r == 0 && g_file_set_contents(path, text, -1, NULL) ? 0 : -1;
}

/* usbfs_memory_mb is read under $UMOCKDEV_DIR/sys: the file exists only
 * in the testbed. */
TEST(usbfs_memory_limit)
{
    static const struct {
        const char *text; /* NULL: no file */
        int mb;
        usb_level level;
    } cases[] = {{NULL, -1, USB_LEVEL_INFO}, {"16\n", 16, USB_LEVEL_WARN},
                 {"255\n", 255, USB_LEVEL_WARN}, {"256\n", 256, USB_LEVEL_OK},
                 {"0\n", 0, USB_LEVEL_OK}, {"1000\n", 1000, USB_LEVEL_OK}};
    mock m;
    usb *u;
    usb_finding f = {0};
    int bad = -1, mb = 0;
    SETUP(&m, &u, NULL);
    char *path = g_strdup_printf("%s/sys/module/usbcore/parameters/"
                                 "usbfs_memory_mb", m.root);
    for (int i = 0; i < (int)(sizeof cases / sizeof cases[0]) && bad < 0; i++) {
        if (cases[i].text && write_text(path, cases[i].text) != 0)
            bad = i;
        else if (usb_check_usbfs_memory(u, &f, &mb) != SL_OK ||
                 mb != cases[i].mb || f.level != cases[i].level ||
                 f.check != USB_CHECK_USBFS_MEMORY)
            bad = i;
        else if (f.level == USB_LEVEL_WARN &&
                 (!strstr(f.text, USB_USBFS_MEMORY_PATH) ||
                  !strstr(f.fix, "usbcore.usbfs_memory_mb=") ||
                  !strstr(f.fix, "/etc/default/grub")))
            bad = i;
        else if (mb == 0 && !strstr(f.text, "unlimited"))
            bad = i;
    }
    report *r = g_new0(report, 1);
    usb_diagnose(u, 0, collect, r); /* system-wide finding, reported first */
    int first_is_usbfs = r->n >= 1 && !r->it[0].has_dev &&
                         r->it[0].f.check == USB_CHECK_USBFS_MEMORY;
    g_free(r);
    g_free(path);
    teardown(&m, u);
    CHECK(bad < 0, "case %d: mb %d level %d text \"%s\"", bad, mb,
          (int)f.level, f.text);
    CHECK(first_is_usbfs, "usb_diagnose did not report usbfs first");
}

/* ---- permission: an unprivileged child against the same testbed ---- */

/* Child mode: diagnose bus:addr as uid NOBODY and print one line per
 * finding: "level check<TAB>text<TAB>fix" (newlines in fix as '|'). */
static int child_diagnose(const char *busaddr)
{
    usb *u = NULL;
    usb_dev_info d[8];
    int bus = 0, addr = 0, n = 0;
    report r = {0};
    if (sscanf(busaddr, "%d:%d", &bus, &addr) != 2)
        return 2;
    if (geteuid() == 0 &&
        (setgroups(0, NULL) != 0 || setgid(NOBODY) != 0 || setuid(NOBODY) != 0))
        return 3;
    if (geteuid() == 0)
        return 3;
    if (usb_new(&u, NULL) != SL_OK || usb_list(u, d, 8, &n) != SL_OK)
        return 4;
    for (int i = 0; i < n && i < 8; i++)
        if (d[i].bus == bus && d[i].address == addr)
            usb_diagnose_device(u, &d[i], collect, &r);
    for (int i = 0; i < r.n; i++) {
        printf("%s %s\t%s\t", usb_level_name(r.it[i].f.level),
               usb_check_name(r.it[i].f.check), r.it[i].f.text);
        for (const char *c = r.it[i].f.fix; *c; c++)
            putchar(*c == '\n' ? '|' : *c);
        putchar('\n');
    }
    usb_free(u);
    return 0;
}

/* Child mode --usbfs-child: print the usbfs limit usb.c reads. */
static int child_usbfs(void)
{
    usb *u = NULL;
    usb_finding f;
    int mb = -2;
    if (usb_new(&u, NULL) != SL_OK)
        return 4;
    usb_check_usbfs_memory(u, &f, &mb);
    printf("%d\n", mb);
    usb_free(u);
    return 0;
}

/* Run this binary as "test_usb MODE ARG", without the umockdev preload
 * when bare; its stdout into out (bounded: 10 s). */
static int run_child(const char *mode, const char *arg, int bare, char *out,
                     size_t cap, int *status)
{
    int fds[2];
    size_t len = 0;
    double end = now_s() + 10.0;
    if (pipe(fds) != 0)
        return -1;
    pid_t pid = fork();
    if (pid < 0)
        return -1;
    if (pid == 0) {
        dup2(fds[1], 1);
        close(fds[0]);
        close(fds[1]);
        if (bare)
            unsetenv("LD_PRELOAD");
        execl("/proc/self/exe", "test_usb", mode, arg, (char *)NULL);
        _exit(127);
    }
    close(fds[1]);
    for (;;) {
        struct pollfd p = {fds[0], POLLIN, 0};
        int left_ms = (int)((end - now_s()) * 1000);
        if (left_ms <= 0 || poll(&p, 1, left_ms) <= 0)
            break;
        ssize_t k = read(fds[0], out + len, cap - 1 - len);
        if (k <= 0)
            break;
        len += (size_t)k;
        if (len >= cap - 1)
            break;
    }
    out[len] = '\0';
    close(fds[0]);
    if (now_s() >= end)
        kill(pid, SIGKILL);
    waitpid(pid, status, 0);
    return 0;
}

/* Without the preload nothing redirects /sys: usb.c itself must read
 * $UMOCKDEV_DIR/sys. */
TEST(sysfs_root_from_umockdev_dir)
{
    char out[256] = "", *dir = g_dir_make_tmp("specklab-usb-XXXXXX", NULL);
    int st = -1, r = -1;
    CHECK(dir, "cannot make a temporary directory");
    char *path = g_strdup_printf("%s/sys/module/usbcore/parameters/"
                                 "usbfs_memory_mb", dir);
    char *old = g_strdup(getenv("UMOCKDEV_DIR"));
    if (write_text(path, "64\n") == 0) {
        setenv("UMOCKDEV_DIR", dir, 1);
        r = run_child("--usbfs-child", "-", 1, out, sizeof out, &st);
        if (old)
            setenv("UMOCKDEV_DIR", old, 1);
        else
            unsetenv("UMOCKDEV_DIR");
    }
    char *cmd = g_strdup_printf("rm -rf '%s'", dir);
    int rm = system(cmd);
    g_free(cmd);
    g_free(path);
    g_free(old);
    g_free(dir);
    CHECK(r == 0 && WIFEXITED(st) && WEXITSTATUS(st) == 0, "child failed");
    CHECK(atoi(out) == 64, "read %s MB, want the 64 under $UMOCKDEV_DIR", out);
    CHECK(rm == 0, "cannot remove the temporary directory");
}

TEST(permission_denied_gives_udev_rule)
{
    mock m;
    usb *u;
    char out[8192], node[600], sock[600], dflt[600];
    int st = 0;
    SETUP(&m, &u, &CAM);
    usb_free(u);
    snprintf(node, sizeof node, "%s/dev/bus/usb/002/003", m.root);
    snprintf(sock, sizeof sock, "%s/ioctl/dev/bus/usb/002/003", m.root);
    snprintf(dflt, sizeof dflt, "%s/ioctl/_default", m.root);
    /* The device node stays root:root 0664, the usual default (0000 when
     * we are not root); the child may enter the testbed (the preload
     * makes its uevent socket there) and reach umockdev's ioctl sockets,
     * which the preload connects to on every open of a /dev path. */
    int prep = geteuid() == 0
                   ? chown(m.root, NOBODY, NOBODY) | chmod(node, 0664) |
                         chmod(sock, 0666) | chmod(dflt, 0666)
                   : chmod(node, 0000);
    int r = prep == 0 ? run_child("--child-diagnose", "2:3", 0, out,
                                  sizeof out, &st)
                      : -1;
    mock_done(&m);
    CHECK(prep == 0, "cannot set up the testbed modes: %s", strerror(errno));
    CHECK(r == 0, "cannot start the child: %s", strerror(errno));
    if (WIFEXITED(st) && WEXITSTATUS(st) == 3)
        SKIP("cannot drop root privileges here");
    CHECK(WIFEXITED(st) && WEXITSTATUS(st) == 0,
          "child status 0x%x, output: %s", st, out);
    /* The camera was still enumerated (sysfs is readable by anyone)... */
    CHECK(strstr(out, "ok speed\tcamera SpeckCam U3") != NULL, "output: %s",
          out);
    /* ...but opening it was refused, with the fix spelled out. */
    CHECK(strstr(out, "error access\tno permission to open "
                 "/dev/bus/usb/002/003 (SpeckCam U3") != NULL,
          "output: %s", out);
    CHECK(strstr(out, "SUBSYSTEM==\"usb\", ATTR{idVendor}==\"1ab2\", "
                 "ATTR{idProduct}==\"0001\", MODE=\"0660\", GROUP=\"plugdev\"")
              != NULL, "no udev rule in: %s", out);
    CHECK(strstr(out, USB_UDEV_RULES_FILE) &&
              strstr(out, "udevadm control --reload-rules"),
          "no rules file / reload command in: %s", out);
}

/* ---- hot-plug ---- */

static void hotplug_case(tc *t, int rescan)
{
    mock m;
    usb *u;
    evlog l = {0};
    SETUP(&m, &u, &CAM);
    int r = rescan ? usb_hotplug_start_rescan(u, 0, log_event, &l)
                   : usb_hotplug_start(u, log_event, &l);
    int mode = usb_hotplug_mode(u);
    int present = r == SL_OK && usb_poll(u, 0) == SL_OK &&
                  count_events(&l, USB_EVENT_ARRIVED, CAM.vid) == 1;
    int arrived = present && mock_add(&m, &DISK) == 0 &&
                  wait_event(u, &l, USB_EVENT_ARRIVED, DISK.vid);
    if (arrived)
        mock_remove(&m, &CAM);
    int left = arrived && wait_event(u, &l, USB_EVENT_LEFT, CAM.vid);
    int i_left = 0;
    for (int i = 0; i < l.n; i++)
        if (l.e[i].kind == USB_EVENT_LEFT)
            i_left = i;
    usb_hotplug_stop(u);
    teardown(&m, u);
    CHECK(r == SL_OK, "hot-plug start failed");
    if (!rescan && mode != USB_HOTPLUG_NATIVE)
        SKIP("libusb has no hot-plug capability here");
    CHECK(mode == (rescan ? USB_HOTPLUG_RESCAN : USB_HOTPLUG_NATIVE), "mode %d",
          mode);
    CHECK(present, "the camera present at start was not reported (%d events)",
          l.n);
    CHECK(arrived, "no arrival event for the added device within 5 s");
    CHECK(left, "no removal event for the unplugged camera within 5 s");
    /* Exactly these three events, and the removal carries what was known
     * at arrival (sysfs is gone by then). */
    CHECK(l.n == 3 && count_events(&l, USB_EVENT_LEFT, DISK.vid) == 0,
          "%d events", l.n);
    CHECK(l.e[i_left].d.bus == 2 && l.e[i_left].d.address == 3 &&
              strcmp(l.e[i_left].d.product, "SpeckCam U3") == 0 &&
              l.e[i_left].d.is_u3v,
          "removal event: bus %d addr %d product \"%s\"", l.e[i_left].d.bus,
          l.e[i_left].d.address, l.e[i_left].d.product);
}

TEST(hotplug_native) { hotplug_case(t, 0); }
TEST(hotplug_rescan_fallback) { hotplug_case(t, 1); }

/* ---- reset ---- */

TEST(reset_reaches_device)
{
    mock m;
    usb *u;
    sl_err e1 = {0}, e2 = {0}, e3 = {0}, e4 = {0};
    char last[64];
    SETUP(&m, &u, &CAM);
    int r1 = usb_reset(u, 2, 3, &e1);
    int n1 = g_atomic_int_get(&m.n_reset);
    g_mutex_lock(&m.lock);
    g_strlcpy(last, m.last_reset, sizeof last);
    g_mutex_unlock(&m.lock);
    g_atomic_int_set(&m.reset_errno, EIO);    /* the reset itself fails */
    int r2 = usb_reset(u, 2, 3, &e2);
    g_atomic_int_set(&m.reset_errno, ENODEV); /* device re-enumerates */
    int r3 = usb_reset(u, 2, 3, &e3);
    int r4 = usb_reset(u, 9, 9, &e4);         /* nothing there */
    int n4 = g_atomic_int_get(&m.n_reset);
    int unknown = g_atomic_int_get(&m.n_unknown);
    int same = strcmp(usb_errmsg(u), e4.msg) == 0;
    teardown(&m, u);
    CHECK(r1 == SL_OK && e1.msg[0] == '\0', "reset: %d %s", r1, e1.msg);
    CHECK(n1 == 1 && strcmp(last, "/dev/bus/usb/002/003") == 0,
          "mock saw %d resets, last on %s", n1, last);
    CHECK(r2 == SL_EIO && strstr(e2.msg, "usb reset of SpeckCam U3") &&
              strstr(e2.msg, "failed"), "%d %s", r2, e2.msg);
    CHECK(r3 == SL_OK, "re-enumeration after reset is success: %s", e3.msg);
    CHECK(r4 == SL_EINVAL && strstr(e4.msg, "no device at bus 9 address 9"),
          "%d %s", r4, e4.msg);
    CHECK(n4 == 3, "mock saw %d resets, want 3", n4);
    CHECK(unknown == 0, "libusb sent %d ioctls the mock does not know",
          unknown);
    CHECK(same, "usb_errmsg differs from the sl_err");
}

/* ---- strings over control transfers ---- */

/* No strings in sysfs: usb_list leaves them empty, usb_diagnose (which
 * opens the device) fetches them as string descriptors through control
 * URBs that the mock answers. */
TEST(strings_from_descriptors)
{
    mock m;
    usb *u;
    fake_dev bare = CAM;
    usb_dev_info d[4];
    int n = 0;
    bare.manufacturer = bare.product = bare.serial = NULL;
    SETUP(&m, &u, &bare);
    m.strings[0] = "Specklab"; /* before any open: no ioctl has run yet */
    m.strings[1] = "SpeckCam U3";
    m.strings[2] = "SC0042";
    report *r = g_new0(report, 1);
    int rl = usb_list(u, d, 4, &n);
    usb_diagnose(u, 0, collect, r);
    teardown(&m, u);
    const item *sp = finding_of(r, USB_CHECK_SPEED, CAM.vid);
    item it = sp ? *sp : (item){0};
    g_free(r);
    CHECK(rl == SL_OK && n == 1 && d[0].product[0] == '\0',
          "sysfs has no strings, yet product \"%s\"", d[0].product);
    CHECK(sp, "no speed finding for the camera");
    CHECK(strcmp(it.dev.product, "SpeckCam U3") == 0 &&
              strcmp(it.dev.manufacturer, "Specklab") == 0 &&
              strcmp(it.dev.serial, "SC0042") == 0,
          "strings \"%s\" \"%s\" \"%s\"", it.dev.manufacturer, it.dev.product,
          it.dev.serial);
    CHECK(strstr(it.f.text, "SpeckCam U3 (1ab2:0001, serial SC0042)") != NULL,
          "text: %s", it.f.text);
}

/* Without a testbed: the real machine (here: no USB at all) must work. */
TEST(no_testbed_real_system)
{
    usb *u = NULL;
    usb_dev_info d[4];
    int n = -1;
    CHECK(getenv("UMOCKDEV_DIR") == NULL, "a testbed leaked from a test");
    CHECK(usb_new(&u, NULL) == SL_OK, "usb_new failed");
    int r = usb_list(u, d, 4, &n);
    usb_free(u);
    usb_free(NULL);
    CHECK(r == SL_OK && n >= 0, "usb_list: %d", r);
}

int main(int argc, char **argv)
{
    static const tc_case cases[] = {
        TC_CASE(no_testbed_real_system),
        TC_CASE(enumerate_identifies_u3v),
        TC_CASE(link_speed),
        TC_CASE(usbfs_memory_limit),
        TC_CASE(sysfs_root_from_umockdev_dir),
        TC_CASE(permission_denied_gives_udev_rule),
        TC_CASE(hotplug_native),
        TC_CASE(hotplug_rescan_fallback),
        TC_CASE(reset_reaches_device),
        TC_CASE(strings_from_descriptors),
    };
    if (argc == 3 && strcmp(argv[1], "--child-diagnose") == 0)
        return child_diagnose(argv[2]);
    if (argc == 3 && strcmp(argv[1], "--usbfs-child") == 0)
        return child_usbfs();
    /* Once only: if the preload still is not there, the tests skip. */
    fx_reexec_preloaded(argv, "SPECKLAB_TEST_USB_REEXEC");
    return tc_main(argv[0], argc, argv, cases,
                   (int)(sizeof cases / sizeof cases[0]));
}
