/* status.h - the one error convention of recon/.
 *
 * Every fallible function returns an int status: SL_OK (0) or a negative
 * SL_E* code.  The human-readable message lives in an sl_err, either inside
 * a handle (read it with the module's *_errmsg(handle)) or, for
 * constructors that have no handle yet, in a caller-supplied sl_err.
 * Messages name what is wrong: the file, the keyword, the pixel.
 */
#ifndef SL_STATUS_H
#define SL_STATUS_H

#include <stdarg.h>

enum {
    SL_OK = 0,
    SL_EINVAL = -1,  /* bad argument or parameter */
    SL_EIO = -2,     /* open/read/write failed (missing file, disk full) */
    SL_ENOMEM = -3,  /* allocation failed */
    SL_EFORMAT = -4, /* file content is wrong: axes, truncation, syntax */
    SL_EDATA = -5,   /* data values are wrong: NaN/Inf, empty */
    SL_ERANGE = -6,  /* a value is outside what is supported */
    SL_EEND = -7     /* no more items (streaming reader exhausted) */
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
/* Short name of a status code ("invalid argument", ...). */
const char *sl_strstatus(int code);

#endif
