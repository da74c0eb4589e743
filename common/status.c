/* status.c - see status.h. */
#include "status.h"

#include <stdio.h>
#include <string.h>

int sl_seterr(sl_err *e, int code, const char *fmt, ...)
{
    if (e) {
        va_list ap;
        e->code = code;
        va_start(ap, fmt);
        vsnprintf(e->msg, sizeof e->msg, fmt, ap);
        va_end(ap);
    }
    return code;
}

void sl_clearerr(sl_err *e)
{
    if (e) {
        e->code = SL_OK;
        e->msg[0] = '\0';
    }
}

const char *sl_strstatus(int code)
{
    switch (code) {
    case SL_OK: return "ok";
    case SL_EINVAL: return "invalid argument";
    case SL_EIO: return "i/o error";
    case SL_ENOMEM: return "out of memory";
    case SL_EFORMAT: return "bad file format";
    case SL_EDATA: return "bad data";
    case SL_ERANGE: return "out of range";
    case SL_EEND: return "end of sequence";
    /* Names stay distinct across modules (the camera's and the client's
     * timeouts are different waits), so the name alone says who failed. */
    case CAMERA_ETIMEOUT: return "camera timeout";
    case CAMERA_ELOST: return "camera control lost";
    case CAMERA_ENODEV: return "no such camera";
    case CLIENT_EUNREACHABLE: return "daemon unreachable";
    case CLIENT_ETIMEOUT: return "daemon reply timeout";
    case CLIENT_EREMOTE: return "daemon refused the request";
    default: return "unknown error";
    }
}
