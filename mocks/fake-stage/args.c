/* args.c - see args.h. */
#include "args.h"

#include <errno.h>
#include <getopt.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "line.h"

static void usage(FILE *f)
{
    fprintf(f,
        "usage: specklab-fake-stage [OPTIONS]\n"
        "A Modbus TCP fake of the specklab stage (drivers/stage_map.h): two\n"
        "wheels that start unhomed, move one slot per --step-ms, home in\n"
        "--home-ms, and fault switches (also registers 100..108 at run time).\n\n"
        "  --port N             TCP port (default 1502; 0 = pick a free one)\n"
        "  --bind ADDR          IPv4 address to listen on (default 127.0.0.1)\n"
        "  --slots-screen N     slots on wheel 0, the phase screens (default 6)\n"
        "  --slots-mask N       slots on wheel 1, the masks (default 6)\n"
        "  --step-ms N          ms per slot step (default 100)\n"
        "  --home-ms N          ms to home (default 2 * step)\n"
        "  --ready-fd FD        write \"READY port=N\\n\" to FD once listening\n"
        "  --magic N            answer this in register 0 (tests a client's check)\n"
        "  --rtu                also serve Modbus RTU on a new pseudo-terminal,\n"
        "                       named on the READY line (rtu=/dev/pts/N)\n"
        "  --rtu-link PATH      --rtu, and make PATH a symlink to its pty\n"
        "  --unit N             RTU unit id answered (default 1; others ignored)\n"
        "  --baud N             RTU speed (default 19200); a client at another\n"
        "                       speed is not understood (no reply)\n"
        "  --parity N|E|O       RTU parity; when given, a client with another\n"
        "                       is not understood (default: not checked)\n"
        "fault switches (register):\n"
        "  --busy-count N       exception 0x06 for the next N requests (100)\n"
        "  --busy               exception 0x06 for every request (101)\n"
        "  --stall              HOME/MOVE never complete (102)\n"
        "  --stall-ms N         then FAULT=STALL after N ms (103, default 1000)\n"
        "  --slow-ms N          delay every reply by N ms (104)\n"
        "  --disconnect-after N close the connection of the N-th request (105)\n"
        "  --disconnect         close each connection at its first request (106)\n"
        "  --fault-screen CODE  start with FAULT=CODE on wheel 0 (107)\n"
        "  --fault-mask CODE    start with FAULT=CODE on wheel 1 (108)\n"
        "serial line faults (--rtu; registers, each counting down per frame):\n"
        "  109 LINE_NOISE / 110 LINE_DROP: a reply gets a byte corrupted / lost\n"
        "  111 LINE_NOISE_RX / 112 LINE_DROP_RX: the same to a request\n"
        "On the line, the disconnect switches leave a request unanswered.\n"
        "Requests that touch only registers >= 100 ignore the fault switches.\n"
        "Prints \"READY port=N\" (with --rtu: \"READY port=N rtu=PATH\") on\n"
        "stdout; SIGINT/SIGTERM exit cleanly.\n");
}

static int parse_int(const char *opt, const char *text, long lo, long hi,
                     int *out)
{
    char *end = NULL;
    errno = 0;
    long v = strtol(text, &end, 0);
    if (errno || end == text || *end || v < lo || v > hi) {
        fprintf(stderr, "specklab-fake-stage: --%s '%s': expected an integer "
                "in %ld..%ld\n", opt, text, lo, hi);
        return -1;
    }
    *out = (int)v;
    return 0;
}

static int parse_parity(const char *text, char *out)
{
    if (strlen(text) != 1 || !strchr("NEO", text[0])) {
        fprintf(stderr, "specklab-fake-stage: --parity '%s': expected N, E "
                "or O\n", text);
        return -1;
    }
    *out = text[0];
    return 0;
}

static int parse_baud(const char *text, int *out)
{
    if (parse_int("baud", text, 1, 4000000, out) < 0)
        return -1;
    if (fake_line_baud_ok(*out))
        return 0;
    fprintf(stderr, "specklab-fake-stage: --baud %s: not a serial port "
            "speed (300 .. 921600)\n", text);
    return -1;
}

enum { O_PORT = 256, O_BIND, O_SS, O_SM, O_STEP, O_HOME, O_READY, O_MAGIC,
       O_BUSYN, O_BUSY, O_STALL, O_STALLMS, O_SLOW, O_DISCN, O_DISC, O_FS,
       O_FM, O_RTU, O_RTULINK, O_UNIT, O_BAUD, O_PARITY };

/* The serial line's options; 1 if c was one of them (*bad set on error). */
static int parse_rtu(int c, const char *n, run_opts *r, int *bad)
{
    switch (c) {
    case O_RTU: r->rtu = 1; return 1;
    case O_RTULINK: r->rtu = 1; r->rtu_link = optarg; return 1;
    case O_UNIT: *bad |= parse_int(n, optarg, 1, 247, &r->unit); return 1;
    case O_BAUD: *bad |= parse_baud(optarg, &r->baud); return 1;
    case O_PARITY: *bad |= parse_parity(optarg, &r->parity); return 1;
    default: return 0;
    }
}

int parse_args(int argc, char **argv, fake_opts *o, run_opts *r)
{
    static const struct option opts[] = {
        {"port", required_argument, NULL, O_PORT},
        {"bind", required_argument, NULL, O_BIND},
        {"slots-screen", required_argument, NULL, O_SS},
        {"slots-mask", required_argument, NULL, O_SM},
        {"step-ms", required_argument, NULL, O_STEP},
        {"home-ms", required_argument, NULL, O_HOME},
        {"ready-fd", required_argument, NULL, O_READY},
        {"magic", required_argument, NULL, O_MAGIC},
        {"busy-count", required_argument, NULL, O_BUSYN},
        {"busy", no_argument, NULL, O_BUSY},
        {"stall", no_argument, NULL, O_STALL},
        {"stall-ms", required_argument, NULL, O_STALLMS},
        {"slow-ms", required_argument, NULL, O_SLOW},
        {"disconnect-after", required_argument, NULL, O_DISCN},
        {"disconnect", no_argument, NULL, O_DISC},
        {"fault-screen", required_argument, NULL, O_FS},
        {"fault-mask", required_argument, NULL, O_FM},
        {"rtu", no_argument, NULL, O_RTU},
        {"rtu-link", required_argument, NULL, O_RTULINK},
        {"unit", required_argument, NULL, O_UNIT},
        {"baud", required_argument, NULL, O_BAUD},
        {"parity", required_argument, NULL, O_PARITY},
        {"help", no_argument, NULL, 'h'},
        {NULL, 0, NULL, 0}};
    int c, bad = 0;
    while ((c = getopt_long(argc, argv, "h", opts, NULL)) != -1) {
        const char *n = NULL;
        for (const struct option *p = opts; p->name; p++)
            if (p->val == c)
                n = p->name;
        if (parse_rtu(c, n, r, &bad))
            continue;
        switch (c) {
        case 'h': usage(stdout); return 1;
        case O_PORT: bad |= parse_int(n, optarg, 0, 65535, &r->port); break;
        case O_BIND: r->bind_addr = optarg; break;
        case O_SS: bad |= parse_int(n, optarg, 1, 64, &o->slots[0]); break;
        case O_SM: bad |= parse_int(n, optarg, 1, 64, &o->slots[1]); break;
        case O_STEP: bad |= parse_int(n, optarg, 0, 60000, &o->step_ms); break;
        case O_HOME: bad |= parse_int(n, optarg, 0, 60000, &o->home_ms); break;
        case O_READY: bad |= parse_int(n, optarg, 0, 1 << 20, &r->ready_fd); break;
        case O_MAGIC: bad |= parse_int(n, optarg, 0, 65535, &o->magic); break;
        case O_BUSYN: bad |= parse_int(n, optarg, 0, 65535, &o->busy_count); break;
        case O_BUSY: o->busy = 1; break;
        case O_STALL: o->stall = 1; break;
        case O_STALLMS: bad |= parse_int(n, optarg, 0, 65535, &o->stall_ms); break;
        case O_SLOW: bad |= parse_int(n, optarg, 0, 65535, &o->slow_ms); break;
        case O_DISCN: bad |= parse_int(n, optarg, 0, 65535, &o->disconnect_after); break;
        case O_DISC: o->disconnect = 1; break;
        case O_FS: bad |= parse_int(n, optarg, 0, 65535, &o->fault[0]); break;
        case O_FM: bad |= parse_int(n, optarg, 0, 65535, &o->fault[1]); break;
        default: bad = 1; break;
        }
    }
    if (optind < argc) {
        fprintf(stderr, "specklab-fake-stage: unexpected argument '%s'\n",
                argv[optind]);
        bad = 1;
    }
    if (bad)
        fprintf(stderr, "specklab-fake-stage: try --help\n");
    return bad ? 2 : 0;
}
