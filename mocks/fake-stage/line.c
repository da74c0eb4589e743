/* line.c - see line.h. */
#define _XOPEN_SOURCE 700 /* posix_openpt, grantpt, unlockpt, ptsname */
#include "line.h"

#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <termios.h>
#include <unistd.h>

#include "fake_regs.h"

#define CHUNK 512

static const struct {
    int baud;
    speed_t code;
} rates[] = {
    {300, B300},       {600, B600},       {1200, B1200},     {2400, B2400},
    {4800, B4800},     {9600, B9600},     {19200, B19200},   {38400, B38400},
    {57600, B57600},   {115200, B115200}, {230400, B230400}, {460800, B460800},
    {921600, B921600},
};
#define NRATES ((int)(sizeof rates / sizeof rates[0]))

static speed_t speed_code(int baud)
{
    for (int i = 0; i < NRATES; i++)
        if (rates[i].baud == baud)
            return rates[i].code;
    return B0;
}

int fake_line_baud_ok(int baud)
{
    return speed_code(baud) != B0;
}

static void nonblock(int fd)
{
    fcntl(fd, F_SETFL, fcntl(fd, F_GETFL) | O_NONBLOCK);
    fcntl(fd, F_SETFD, FD_CLOEXEC);
}

/* link -> pts, replacing only a symlink (never a file or a device). */
static int make_link(fake_line *l, const char *link, char *why, size_t nwhy)
{
    struct stat st;
    char tmp[600];
    if (lstat(link, &st) == 0 && !S_ISLNK(st.st_mode)) {
        snprintf(why, nwhy, "--rtu-link %s exists and is not a symlink", link);
        return -1;
    }
    snprintf(tmp, sizeof tmp, "%s.%ld.tmp", link, (long)getpid());
    unlink(tmp);
    if (symlink(l->pts, tmp) < 0 || rename(tmp, link) < 0) {
        snprintf(why, nwhy, "--rtu-link %s: %s", link, strerror(errno));
        unlink(tmp);
        return -1;
    }
    snprintf(l->link, sizeof l->link, "%s", link);
    return 0;
}

static int open_pty(fake_line *l, char *why, size_t nwhy)
{
    struct termios t;
    l->master = posix_openpt(O_RDWR | O_NOCTTY);
    if (l->master < 0 || grantpt(l->master) < 0 || unlockpt(l->master) < 0 ||
        !ptsname(l->master)) {
        snprintf(why, nwhy, "pseudo-terminal: %s", strerror(errno));
        return -1;
    }
    snprintf(l->pts, sizeof l->pts, "%s", ptsname(l->master));
    l->hold = open(l->pts, O_RDWR | O_NOCTTY);
    if (l->hold < 0 || tcgetattr(l->hold, &t) < 0) {
        snprintf(why, nwhy, "%s: %s", l->pts, strerror(errno));
        return -1;
    }
    /* Raw both ways: no byte translated, echoed or taken as a signal.
     * The termios is the pty's, so the master side is raw too. */
    cfmakeraw(&t);
    cfsetispeed(&t, speed_code(l->baud));
    cfsetospeed(&t, speed_code(l->baud));
    t.c_cc[VMIN] = 1;
    t.c_cc[VTIME] = 0;
    if (tcsetattr(l->hold, TCSANOW, &t) < 0) {
        snprintf(why, nwhy, "%s: raw mode: %s", l->pts, strerror(errno));
        return -1;
    }
    nonblock(l->master);
    fcntl(l->hold, F_SETFD, FD_CLOEXEC);
    return 0;
}

int fake_line_open(fake_line *l, const char *link, int baud, char parity,
                   char *why, size_t nwhy)
{
    int sv[2];
    memset(l, 0, sizeof *l);
    l->master = l->hold = l->near = l->far = -1;
    l->baud = baud;
    l->parity = parity;
    if (!fake_line_baud_ok(baud)) {
        snprintf(why, nwhy, "--baud %d: not a serial port speed", baud);
        return -1;
    }
    if (open_pty(l, why, nwhy) < 0)
        goto fail;
    if (socketpair(AF_UNIX, SOCK_STREAM, 0, sv) < 0) {
        snprintf(why, nwhy, "socketpair: %s", strerror(errno));
        goto fail;
    }
    l->near = sv[0];
    l->far = sv[1];
    nonblock(l->far);
    fcntl(l->near, F_SETFD, FD_CLOEXEC);
    if (link && *link && make_link(l, link, why, nwhy) < 0)
        goto fail;
    return 0;
fail:
    fake_line_close(l);
    return -1;
}

void fake_line_close(fake_line *l)
{
    int *fds[] = {&l->master, &l->hold, &l->near, &l->far};
    for (size_t i = 0; i < sizeof fds / sizeof fds[0]; i++) {
        if (*fds[i] >= 0)
            close(*fds[i]);
        *fds[i] = -1;
    }
    if (l->link[0]) {
        unlink(l->link);
        l->link[0] = '\0';
    }
}

/* The client's speed and parity, as the pty keeps them, against the
 * stage's: 1 when the stage would understand the bytes. */
static int understood(const fake_line *l)
{
    struct termios t;
    if (tcgetattr(l->hold, &t) < 0)
        return 1;
    if (cfgetospeed(&t) != speed_code(l->baud))
        return 0;
    if (!l->parity)
        return 1;
    char p = !(t.c_iflag & INPCK) ? 'N' : (t.c_cflag & PARODD) ? 'O' : 'E';
    return p == l->parity;
}

/* The damaged byte: the last one before the CRC, never a length or the
 * function code, so a corrupted frame keeps its shape and only its CRC
 * can tell (and a shortened one is one byte short, never longer). */
static int damage(uint8_t *b, int n, int fault)
{
    if (n < 4 || fault == LINE_CLEAN)
        return n;
    int at = n - 3;
    if (fault == LINE_NOISE) {
        b[at] ^= 0x10; /* one bit: CRC-16 catches every single-bit error */
        return n;
    }
    memmove(b + at, b + at + 1, (size_t)(n - at - 1));
    return n - 1;
}

static void put(int fd, const uint8_t *b, int n)
{
    while (n > 0) {
        ssize_t w = write(fd, b, (size_t)n);
        if (w < 0 && errno == EINTR)
            continue;
        if (w <= 0)
            return; /* nobody listening and the pty full: lost on the wire */
        b += w;
        n -= (int)w;
    }
}

void fake_line_inbound(fake_line *l, uint16_t *regs)
{
    uint8_t b[CHUNK];
    ssize_t n = read(l->master, b, sizeof b);
    if (n <= 0)
        return;
    if (!understood(l)) {
        l->misheard++;
        return;
    }
    int fault = LINE_CLEAN;
    if (regs[FAKE_REG_LINE_NOISE_RX] > 0) {
        regs[FAKE_REG_LINE_NOISE_RX]--;
        fault = LINE_NOISE;
    } else if (regs[FAKE_REG_LINE_DROP_RX] > 0) {
        regs[FAKE_REG_LINE_DROP_RX]--;
        fault = LINE_DROP;
    }
    put(l->far, b, damage(b, (int)n, fault));
}

int fake_line_reply_fault(uint16_t *regs)
{
    if (regs[FAKE_REG_LINE_NOISE] > 0) {
        regs[FAKE_REG_LINE_NOISE]--;
        return LINE_NOISE;
    }
    if (regs[FAKE_REG_LINE_DROP] > 0) {
        regs[FAKE_REG_LINE_DROP]--;
        return LINE_DROP;
    }
    return LINE_CLEAN;
}

void fake_line_outbound(fake_line *l, int fault)
{
    uint8_t b[CHUNK];
    ssize_t n = read(l->far, b, sizeof b);
    if (n > 0)
        put(l->master, b, damage(b, (int)n, fault));
}

void fake_line_drain(fake_line *l)
{
    uint8_t b[CHUNK];
    int fl = fcntl(l->near, F_GETFL);
    fcntl(l->near, F_SETFL, fl | O_NONBLOCK);
    while (read(l->near, b, sizeof b) > 0)
        ;
    fcntl(l->near, F_SETFL, fl);
}
