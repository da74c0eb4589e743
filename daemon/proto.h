/* proto.h - the JSON of daemon/PROTOCOL.md: reply and event lines, and the
 * `run` and `recon` objects built from catalogue rows (json-glib only; no
 * JSON is ever formatted by hand).  Pure functions: any thread may call
 * them (the *_node functions that take a catalog use that handle, which
 * must belong to the calling thread).
 */
#ifndef SL_DAEMON_PROTO_H
#define SL_DAEMON_PROTO_H

#include <json-glib/json-glib.h>

#include "catalog.h"
#include "server.h"

/* A request awaiting its reply: where it goes and the id to echo. */
typedef struct proto_req {
    server_token tok;
    gint64 id;
    int has_id;        /* 0: the reply's id is null */
} proto_req;

/* {"id": id, "ok": true, "result": result}; takes result (NULL: {}). */
char *proto_reply_ok(const proto_req *q, JsonNode *result);
/* {"id": id, "ok": false, "error": {"code": code, "message": ...}} */
char *proto_reply_error(const proto_req *q, const char *code, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));

/* Event lines. */
char *proto_event_state(const char *run, catalog_state st, const char *reason);
char *proto_event_progress(const char *run, int acquired, int requested, int failed);
/* Takes recon. */
char *proto_event_recon(const char *run, JsonNode *recon);

/* The `run` object (r0_m, seeing_arcsec: the run's own measurement, from
 * the r0 history of its screen). */
JsonNode *proto_run_node(catalog *c, const catalog_run *r);
/* The `recon` object. */
JsonNode *proto_recon_node(const catalog_recon *r);

/* Builder shorthands: a member with a value; NaN doubles, 0 times and
 * NULL strings become null. */
void proto_add_str(JsonBuilder *b, const char *key, const char *v);
void proto_add_int(JsonBuilder *b, const char *key, gint64 v);
void proto_add_dbl(JsonBuilder *b, const char *key, double v);
void proto_add_bool(JsonBuilder *b, const char *key, int v);
void proto_add_time(JsonBuilder *b, const char *key, int64_t t_ms);
/* A number of a request line that json-glib would misread: an integer
 * beyond gint64, which it wraps silently (2^64 - 1 reads as -1, 2^63 as
 * -2^63), or a numeral JSON does not have (hex 0x10, octal 010, .5),
 * which it accepts. */
typedef struct proto_badnum {
    char literal[48];   /* as written (cut) */
    char key[48];       /* the member it is the value of (in an array: the
                         * array's), "" at the top level of an array */
    int top_id;         /* it is the request's "id" */
    int not_json;       /* not a JSON number at all */
} proto_badnum;

/* 1 when every number of the JSON text (already parsed by json-glib) is
 * read as written; else 0 with the first one that is not in *bad. */
int proto_numbers_ok(const char *text, size_t len, proto_badnum *bad);
/* Parse a JSON object text into a node (NULL when absent or not JSON). */
JsonNode *proto_parse_object(const char *text);
/* Serialise (compact) and release the node. */
char *proto_take_string(JsonNode *n);

#endif
