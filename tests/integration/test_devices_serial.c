/* test_devices_serial.c - `specklab devices --stage DEVICE` names why a
 * stage on a serial port (Modbus RTU) cannot be used
 * (drivers/stage_probe.h), each case against its own fake stage on a
 * pseudo-terminal (bin/specklab-fake-stage --rtu, which answers only a
 * client at its --baud and, when given, its --parity):
 *   missing        a path that does not exist, and a link to one gone;
 *   not_a_tty      a regular file;
 *   permission     the fake's pty at mode 0000, opened by a user who is
 *                  not root: "permission denied" and the dialout hint;
 *   wrong_baud     the stage at 9600 baud, asked at 19200: no reply at
 *                  19200, it answers at 9600, set baud=9600;
 *   wrong_parity   the stage at parity O, asked at E: it answers at O;
 *   line_noise     the right settings with 2 replies corrupted on the
 *                  line: connected, and 2 damaged replies rejected.
 * No network namespace: the pty and the fake's TCP port (its fault
 * switches) are this host's, and the camera listing finds what it finds.
 */
#include "daemon_fx.h"
#include "matrix_fx.h"

#include <grp.h>

#include "../../mocks/fake-stage/fake_regs.h"

#define NOBODY 65534

static int has(const char *hay, const char *needle)
{
    return hay && needle && strstr(hay, needle) != NULL;
}

/* A fake stage serving RTU on a new pty: extra flags NULL-terminated. */
static int rtu_stage(fx_proc *p, int *port, char tty[96], const char *const *extra)
{
    char bin[PATH_MAX], line[192];
    char *argv[16] = {bin, "--port", "0", "--rtu"};
    int n = 4;
    for (int i = 0; extra && extra[i] && n < 14; i++)
        argv[n++] = (char *)extra[i];
    argv[n] = NULL;
    fx_bin(bin, sizeof bin, "specklab-fake-stage");
    return fx_spawn(p, argv, NULL, NULL, NULL) != 0 ||
                   fx_wait_ready(p, line, sizeof line, 10) != 0 ||
                   sscanf(line, "READY port=%d rtu=%95s", port, tty) != 2
               ? -1
               : 0;
}

static void as_nobody(void *arg)
{
    (void)arg;
    if (setgroups(0, NULL) != 0 || setgid(NOBODY) != 0 || setuid(NOBODY) != 0)
        _exit(126);
}

/* `specklab devices --stage dev EXTRA...`'s stdout into out; its exit
 * status.  nobody: run it as uid 65534 (the caller is root). */
static int devices(const char *dev, const char *const *extra, int nobody, char *out, size_t n)
{
    char bin[PATH_MAX];
    char *argv[16] = {bin, "devices", "--stage", (char *)dev};
    int k = 4;
    for (int i = 0; extra && extra[i] && k < 14; i++)
        argv[k++] = (char *)extra[i];
    argv[k] = NULL;
    fx_bin(bin, sizeof bin, "specklab");
    return fx_run(argv, NULL, nobody ? as_nobody : NULL, NULL, out, n, 60);
}

TEST(missing)
{
    char dir[] = "/tmp/sl_devser.XXXXXX", path[64], link[64], out[8192];
    CHECK(mkdtemp(dir), "mkdtemp: %s", strerror(errno));
    snprintf(path, sizeof path, "%s/ttyUSB9", dir);
    snprintf(link, sizeof link, "%s/by-id", dir);
    int rc = devices(path, NULL, 0, out, sizeof out);
    int lk = symlink(path, link);
    char out2[8192] = "";
    int rc2 = lk == 0 ? devices(link, NULL, 0, out2, sizeof out2) : -1;
    unlink(link);
    rmdir(dir);
    CHECK(rc == 0 && has(out, "no such device") && has(out, "/dev/serial/by-id"),
          "a missing device (exit %d):\n%s", rc, out);
    CHECK(rc2 == 0 && has(out2, "no such device (a link to") && has(out2, "ttyUSB9"),
          "a link to a missing device (exit %d):\n%s", rc2, out2);
}

TEST(not_a_tty)
{
    char path[] = "/tmp/sl_devser_file.XXXXXX", out[8192];
    int fd = mkstemp(path);
    CHECK(fd >= 0, "mkstemp: %s", strerror(errno));
    close(fd);
    int rc = devices(path, NULL, 0, out, sizeof out);
    unlink(path);
    CHECK(rc == 0 && has(out, "not a serial port"), "a regular file (exit %d):\n%s", rc, out);
}

TEST(permission)
{
    fx_proc st;
    int port;
    char tty[96], out[8192];
    CHECK(rtu_stage(&st, &port, tty, NULL) == 0, "the fake stage did not start");
    int nobody = geteuid() == 0;   /* root opens anything: ask as another user */
    int rc = chmod(tty, 0) == 0 ? devices(tty, NULL, nobody, out, sizeof out) : -2;
    fx_stop(&st, SIGTERM, 5);
    if (rc == 126 || rc == 127 || rc == -2)   /* no setuid, or bin/ not theirs to run */
        SKIP("cannot run specklab as uid %d or chmod %s here (exit %d)", NOBODY, tty, rc);
    CHECK(rc == 0 && has(out, "permission denied") && has(out, "mode 0000") &&
              has(out, "dialout") && has(out, "usermod -aG dialout"),
          "a pty at mode 0000 (exit %d):\n%s", rc, out);
}

/* A fake stage with flags fake, asked by `specklab devices` with cli. */
static int ask_fake(const char *const *fake, const char *const *cli, char *out, size_t n)
{
    fx_proc st;
    int port;
    char tty[96];
    if (rtu_stage(&st, &port, tty, fake) != 0) {
        fx_stop(&st, SIGKILL, 5);
        snprintf(out, n, "the fake stage did not start");
        return -1;
    }
    int rc = devices(tty, cli, 0, out, n);
    fx_stop(&st, SIGTERM, 5);
    return rc;
}

TEST(wrong_baud)
{
    char out[8192];
    const char *const fake[] = {"--baud", "9600", NULL};
    int rc = ask_fake(fake, NULL, out, sizeof out);
    CHECK(rc == 0 && has(out, "no reply at 19200 baud") && has(out, "answers at 9600 baud") &&
              has(out, "baud=9600"),
          "the stage at 9600 baud, asked at 19200 (exit %d):\n%s", rc, out);
}

TEST(wrong_parity)
{
    char out[8192];
    const char *const fake[] = {"--parity", "O", NULL};
    const char *const cli[] = {"--parity", "E", "--json", NULL};
    int rc = ask_fake(fake, cli, out, sizeof out);
    JsonNode *j = rc == 0 ? json_from_string(out, NULL) : NULL;
    const char *err = js(j, "stage.error"), *fix = js(j, "stage.fix");
    int ok = j && has(js(j, "stage.diagnosis"), "settings") && has(err, "parity E (even)") &&
             has(err, "answers at 19200 baud, parity O") && has(fix, "parity=O");
    if (j)
        json_node_unref(j);
    CHECK(ok, "the stage at parity O, asked at E (exit %d):\n%s", rc, out);
}

TEST(line_noise)
{
    fx_proc st;
    int port;
    char tty[96], out[8192];
    CHECK(rtu_stage(&st, &port, tty, NULL) == 0, "the fake stage did not start");
    int poked = mx_stage_poke(port, FAKE_REG_LINE_NOISE, 2);
    int rc = poked == 0 ? devices(tty, NULL, 0, out, sizeof out) : -1;
    fx_stop(&st, SIGTERM, 5);
    CHECK(poked == 0, "the fault switch");
    CHECK(rc == 0 && has(out, "connected") && has(out, "screen wheel") &&
              has(out, "line: 2 damaged replies rejected"),
          "two corrupted replies (exit %d):\n%s", rc, out);
}

TC_MAIN(TC_CASE(missing), TC_CASE(not_a_tty), TC_CASE(permission), TC_CASE(wrong_baud),
        TC_CASE(wrong_parity), TC_CASE(line_noise))
