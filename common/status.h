/* status.h - the one error convention of specklab, every module's.
 *
 * Every fallible function returns an int status: SL_OK (0) or a negative
 * code.  The human-readable message lives in an sl_err, either inside a
 * handle (read it with the module's *_errmsg(handle)) or, for constructors
 * that have no handle yet, in a caller-supplied sl_err.  Messages name what
 * is wrong: the file, the keyword, the pixel, the camera's address.
 *
 * One code space, cut into a range per module (libmodbus's MODBUS_ENOBASE
 * habit), so that a code read from a log, a test or the wire names its
 * module without knowing who returned it, and sl_strstatus names them all:
 *
 *   range       base              module
 *   -1 .. -19   SL_EBASE_CORE     every module: SL_E* (recon, schema, the
 *                                 daemon and the stage driver have no others)
 *   -20 .. -29  SL_EBASE_CAMERA   drivers/camera.h: CAMERA_E*
 *   -30 .. -39  SL_EBASE_CLIENT   cli/client.h: CLIENT_E*
 *   -40 ..      SL_EBASE_NEXT     free
 *
 * A module's codes are its base minus 0, 1, 2...; its range ends where the
 * next base begins.  The codes of every module are declared here, not in the
 * module's header, because sl_strstatus (below everything) must name them.
 * A module that needs codes of its own takes the next free range here
 * (SL_EBASE_NEXT, then moves SL_EBASE_NEXT down by 10), adds its names to
 * sl_strstatus and its codes to tests/unit/test_status.c.  Values never
 * change once given out: tests compare them and logs keep them.
 */
#ifndef SL_STATUS_H
#define SL_STATUS_H

#include <stdarg.h>

#define SL_EBASE_CORE 0
#define SL_EBASE_CAMERA (-20)
#define SL_EBASE_CLIENT (-30)
#define SL_EBASE_NEXT (-40)

enum {
    SL_OK = 0,
    SL_EINVAL = SL_EBASE_CORE - 1,  /* bad argument or parameter */
    SL_EIO = SL_EBASE_CORE - 2,     /* open/read/write failed (missing file, disk full) */
    SL_ENOMEM = SL_EBASE_CORE - 3,  /* allocation failed */
    SL_EFORMAT = SL_EBASE_CORE - 4, /* file content is wrong: axes, truncation, syntax */
    SL_EDATA = SL_EBASE_CORE - 5,   /* data values are wrong: NaN/Inf, empty */
    SL_ERANGE = SL_EBASE_CORE - 6,  /* a value is outside what is supported */
    SL_EEND = SL_EBASE_CORE - 7     /* no more items (streaming reader exhausted) */
};

/* The camera driver (drivers/camera.h says when each is returned). */
enum {
    CAMERA_ETIMEOUT = SL_EBASE_CAMERA - 0, /* no frame / no reply within the deadline */
    CAMERA_ELOST = SL_EBASE_CAMERA - 1,    /* control of the camera lost: reconnect */
    CAMERA_ENODEV = SL_EBASE_CAMERA - 2    /* no such camera, or it does not answer */
};

/* The control-socket client (cli/client.h says when each is returned). */
enum {
    CLIENT_EUNREACHABLE = SL_EBASE_CLIENT - 0, /* no daemon listening at the socket */
    CLIENT_ETIMEOUT = SL_EBASE_CLIENT - 1,     /* no reply within the deadline */
    CLIENT_EREMOTE = SL_EBASE_CLIENT - 2       /* the daemon answered {"ok": false} */
};

#define SL_ERRMSG_MAX 512

typedef struct sl_err {
    int code;
    char msg[SL_ERRMSG_MAX];
} sl_err;

/* Record code and a printf-style message in e (NULL allowed); returns code
 * so callers can write `return sl_seterr(e, SL_EIO, "...")`. */
int sl_seterr(sl_err *e, int code, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));
void sl_clearerr(sl_err *e);
/* Short name of any module's status code ("invalid argument", "camera
 * control lost", ...); "unknown error" for a code no module declares. */
const char *sl_strstatus(int code);

#endif
