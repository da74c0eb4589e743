/* args.h - bin/specklab-fake-stage's command line (see --help). */
#ifndef SL_FAKE_ARGS_H
#define SL_FAKE_ARGS_H

#include "model.h"

typedef struct run_opts {
    int port, ready_fd;
    const char *bind_addr;
    int rtu, unit, baud; /* --rtu: also serve RTU on a pty */
    char parity;         /* --parity, 0: not checked */
    const char *rtu_link;
} run_opts;

/* Fill o and r from argv (their defaults set by the caller).  Returns 0
 * to run, 1 after --help, 2 on a usage error (said on stderr). */
int parse_args(int argc, char **argv, fake_opts *o, run_opts *r);

#endif
