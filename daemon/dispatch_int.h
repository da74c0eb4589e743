/* dispatch_int.h - shared by dispatch.c (parsing, commands that act) and
 * query.c (commands that only read).  Not for other modules. */
#ifndef SL_DAEMON_DISPATCH_INT_H
#define SL_DAEMON_DISPATCH_INT_H

#include "dispatch.h"
#include "proto.h"

/* One request in hand.  A handler returns NULL after completing (or
 * scheduling) the reply itself, or the reply line to send now. */
typedef struct request {
    daemon_ctx *d;
    proto_req q;
    JsonObject *args;    /* never NULL (empty when absent) */
    const char *cmd;
} request;

typedef char *(*handler_fn)(request *rq);

/* Argument getters: SL_OK (value set, or absent and optional: *present
 * 0), else a bad-request reply line in *reply. */
int arg_int(request *rq, const char *key, int required, gint64 lo, gint64 hi, gint64 *out,
            int *present, char **reply);
int arg_num(request *rq, const char *key, int required, double lo, double hi, double *out,
            int *present, char **reply);
/* A string, or with allow_int an integer given as its decimal text. */
int arg_str(request *rq, const char *key, int required, int allow_int, char **out,
            char **reply);
/* `run`: a uuid or unique prefix -> the canonical uuid (not-found). */
int arg_run(request *rq, const char *key, int required, char uuid[CATALOG_UUID_LEN + 1],
            int *present, char **reply);
/* ISO-8601 / date / integer unix seconds -> ms; absent: 0. */
int arg_since(request *rq, int64_t *since_ms, char **reply);

char *reply_ok(request *rq, JsonNode *result);
char *reply_err(request *rq, const char *code, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));

/* query.c */
char *cmd_status(request *rq);
char *cmd_devices(request *rq);
char *cmd_runs(request *rq);
char *cmd_run(request *rq);
char *cmd_screens(request *rq);
char *cmd_masks(request *rq);

#endif
