/* stage_probe.c - see stage_probe.h. */
#define _GNU_SOURCE
#include "stage_probe.h"

#include <errno.h>
#include <fcntl.h>
#include <grp.h>
#include <stdio.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

/* The scan's request: long enough for an identity reply (~25 bytes) at
 * 2400 baud plus the RTU gap, short enough to try 21 settings in ~3 s. */
#define SCAN_RESPONSE_MS 150
#define SCAN_CALL_MS 300

static const int scan_bauds[] = {9600, 19200, 38400, 57600, 115200, 4800, 2400};
static const char scan_parities[] = "ENO";

const char *stage_probe_verdict_name(stage_probe_verdict v)
{
    switch (v) {
    case STAGE_PROBE_OK: return "ok";
    case STAGE_PROBE_MISSING: return "missing";
    case STAGE_PROBE_DENIED: return "permission";
    case STAGE_PROBE_NOT_TTY: return "not-a-tty";
    case STAGE_PROBE_SETTINGS: return "settings";
    case STAGE_PROBE_SILENT: return "no-reply";
    default: return "error";
    }
}

static const char *parity_name(char p)
{
    return p == 'N' ? "N (none)" : p == 'O' ? "O (odd)" : "E (even)";
}

/* Permission denied: who may open it, and how to be among them. */
static void denied(const char *dev, const struct stat *st, stage_probe_result *out)
{
    const struct group *g = getgrgid(st->st_gid);
    char grp[64];
    snprintf(grp, sizeof grp, "%s", g ? g->gr_name : "?");
    unsigned mode = (unsigned)st->st_mode & 07777;
    out->verdict = STAGE_PROBE_DENIED;
    snprintf(out->what, sizeof out->what, "stage %s: permission denied (group %s, mode %04o)",
             dev, grp, mode);
    if ((mode & 060) == 060 && strcmp(grp, "root") != 0)
        snprintf(out->fix, sizeof out->fix, "add yourself to group %s (serial ports are group "
                 "dialout on Debian): sudo usermod -aG %s $USER, then log in again", grp, grp);
    else
        snprintf(out->fix, sizeof out->fix, "mode %04o lets no group open it: a serial port "
                 "is root:dialout 0660 (udev); sudo chgrp dialout %s && sudo chmod 0660 %s, and "
                 "sudo usermod -aG dialout $USER, then log in again", mode, dev, dev);
}

/* The node alone: 0 when it opens as a serial port, else the verdict. */
static int look_at_node(const char *dev, stage_probe_result *out)
{
    struct stat st;
    char target[256];
    if (stat(dev, &st) != 0) {
        ssize_t n = errno == ENOENT ? readlink(dev, target, sizeof target - 1) : -1;
        target[n > 0 ? n : 0] = '\0';
        out->verdict = errno == ENOENT ? STAGE_PROBE_MISSING : STAGE_PROBE_ERROR;
        if (n > 0)
            snprintf(out->what, sizeof out->what, "stage %s: no such device (a link to %s, "
                     "which is gone: unplugged?)", dev, target);
        else
            snprintf(out->what, sizeof out->what, "stage %s: %s", dev,
                     errno == ENOENT ? "no such device" : strerror(errno));
        snprintf(out->fix, sizeof out->fix, "is the adapter plugged in? ls -l /dev/serial/by-id/ "
                 "names USB serial adapters; set [stage] device to one (specklab: --stage PATH)");
        return -1;
    }
    int fd = open(dev, O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC);
    if (fd < 0 && (errno == EACCES || errno == EPERM)) {
        denied(dev, &st, out);
        return -1;
    }
    if (fd < 0 || !isatty(fd)) {
        out->verdict = fd < 0 ? STAGE_PROBE_ERROR : STAGE_PROBE_NOT_TTY;
        snprintf(out->what, sizeof out->what, "stage %s: %s", dev,
                 fd < 0 ? strerror(errno) : "not a serial port");
        snprintf(out->fix, sizeof out->fix, "set [stage] device to the stage's serial port "
                 "(ls -l /dev/serial/by-id/)");
    }
    if (fd >= 0)
        close(fd);
    return fd < 0 || out->verdict != STAGE_PROBE_OK ? -1 : 0;
}

/* The stage's identity at baud and parity; SL_OK when it answered. */
static int ask(const stage_config *cfg, int baud, char parity, int quick, sl_err *e)
{
    stage_config c = *cfg;
    stage *s = NULL;
    stage_ident id;
    c.baud = baud;
    c.parity = parity;
    if (quick) {
        c.response_timeout_ms = SCAN_RESPONSE_MS;
        c.call_timeout_ms = SCAN_CALL_MS;
    }
    int rc = stage_new(&s, &c, e);
    if (rc == SL_OK && (rc = stage_info(s, &id)) != SL_OK)
        sl_seterr(e, rc, "%s", stage_errmsg(s));
    stage_free(s);
    return rc;
}

/* Every other baud rate and parity; 1 with out's baud and parity set when
 * the stage answered at one. */
static int scan(const stage_config *cfg, stage_probe_result *out)
{
    sl_err e = {0};
    /* the configured parity first: on a line that ignores parity the baud
     * rate alone is then named */
    char order[3] = {cfg->parity};
    for (int i = 0, k = 1; scan_parities[i] && k < 3; i++)
        if (scan_parities[i] != cfg->parity)
            order[k++] = scan_parities[i];
    for (size_t b = 0; b < sizeof scan_bauds / sizeof scan_bauds[0]; b++)
        for (int p = 0; p < 3; p++) {
            if ((scan_bauds[b] == cfg->baud && order[p] == cfg->parity) ||
                ask(cfg, scan_bauds[b], order[p], 1, &e) != SL_OK)
                continue;
            out->baud = scan_bauds[b];
            out->parity = order[p];
            return 1;
        }
    return 0;
}

int stage_probe_serial(const stage_config *cfg, int do_scan, stage_probe_result *out)
{
    memset(out, 0, sizeof *out);
    if (!cfg || !cfg->backend || strcmp(cfg->backend, "rtu") != 0 || !cfg->device)
        return SL_EINVAL;
    if (look_at_node(cfg->device, out) != 0)
        return SL_OK;
    sl_err e = {0};
    int rc = ask(cfg, cfg->baud, cfg->parity, 0, &e);
    if (rc == SL_OK)
        return SL_OK;
    out->verdict = STAGE_PROBE_ERROR;
    snprintf(out->what, sizeof out->what, "%s", e.msg);
    if (rc != SL_EIO || !strstr(e.msg, "no reply"))
        return SL_OK;   /* an answer, but not a stage's: the driver's words say what */
    out->verdict = STAGE_PROBE_SILENT;
    snprintf(out->what, sizeof out->what, "stage %s: no reply at %d baud, parity %s, unit %d",
             cfg->device, cfg->baud, parity_name(cfg->parity), cfg->unit_id);
    if (do_scan && scan(cfg, out)) {
        out->verdict = STAGE_PROBE_SETTINGS;
        snprintf(out->what + strlen(out->what), sizeof out->what - strlen(out->what),
                 "; it answers at %d baud, parity %s", out->baud, parity_name(out->parity));
        snprintf(out->fix, sizeof out->fix, "set [stage] baud=%d and parity=%c (specklab: "
                 "--baud %d --parity %c)", out->baud, out->parity, out->baud, out->parity);
        return SL_OK;
    }
    if (do_scan)
        snprintf(out->fix, sizeof out->fix, "nothing answers at 2400..115200 baud with any "
                 "parity either: check the stage is powered, the wiring (RS-485 A/B swapped?) "
                 "and its unit id ([stage] unit)");
    else
        snprintf(out->fix, sizeof out->fix, "check the baud rate and parity against the "
                 "stage's (specklab devices --stage %s tries the others), that it is powered, "
                 "the wiring and its unit id ([stage] unit)", cfg->device);
    return SL_OK;
}
