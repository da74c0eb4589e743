/* cmd_daemon.h - the subcommands that talk to specklabd, and the helpers
 * they share (prefix dcmd_).
 *
 * Every subcommand takes argv with argv[0] = "specklab SUBCOMMAND" (as in
 * cli.h) and returns 0 ok, 1 failure (daemon unreachable, error reply, a
 * run that failed), 2 usage error.  Each accepts --socket PATH (default
 * $SPECKLAB_SOCKET, else ./var/specklabd.sock) and --json (the daemon's
 * result object, or a JSON array for the experiment, on one line).
 */
#ifndef SL_CMD_DAEMON_H
#define SL_CMD_DAEMON_H

#include <glib.h>
#include <json-glib/json-glib.h>

#include "client.h"

/* specklab experiment binary-bench --screens 1,2,3 --masks nrm17 ... */
int cmd_experiment(int argc, char **argv);
/* specklab runs list|show */
int cmd_runs(int argc, char **argv);
/* specklab screens list|show */
int cmd_screens(int argc, char **argv);
/* specklab masks list */
int cmd_masks(int argc, char **argv);
/* specklab daemon status */
int cmd_daemon(int argc, char **argv);
/* specklab export RUN-ID [-o DIR] */
int cmd_export(int argc, char **argv);
/* specklab recon RUN-ID [--method M]: on-demand reconstruction of a
 * catalogued run by the daemon; same argv as cmd_recon. */
int cmd_recon_run(int argc, char **argv);
/* Nonzero when arg is not an existing file and reads as a run uuid or a
 * prefix of one (4..36 characters of hex digits and '-'): cmd_recon hands
 * such an argument to cmd_recon_run. */
int cmd_recon_is_run_id(const char *arg);

/* ---- shared by the cmd_*.c files above ---- */

/* Connection timeout: a live daemon accepts at once. */
#define DCMD_CONNECT_MS 3000
/* Queries answer from the catalogue: seconds at most. */
#define DCMD_QUERY_MS 30000

/* The options every daemon subcommand has. */
typedef struct dcmd_opts {
    char *socket;
    int json;
    GOptionEntry entries[3];
} dcmd_opts;

/* Add --socket and --json to ctx (o must outlive the parse). */
void dcmd_opts_add(dcmd_opts *o, GOptionContext *ctx);
void dcmd_opts_clear(dcmd_opts *o);
/* Connect, or print "PROG: cannot reach specklabd at ..." and return NULL. */
client *dcmd_connect(const dcmd_opts *o, const char *prog);
/* client_call that prints "PROG: message" on failure; returns 0 or 1. */
int dcmd_call(client *c, const char *prog, const char *cmd, JsonObject *args,
              int timeout_ms, JsonObject **result);
/* Print o as one JSON line (object or array node) on stdout. */
void dcmd_print_node(JsonNode *n);
void dcmd_print_object(JsonObject *o);

/* Safe member access: NULL / NAN / def when absent, null or ill-typed. */
const char *dcmd_str(JsonObject *o, const char *k);
double dcmd_num(JsonObject *o, const char *k);
gint64 dcmd_int(JsonObject *o, const char *k, gint64 def);
JsonObject *dcmd_obj(JsonObject *o, const char *k);
JsonArray *dcmd_arr(JsonObject *o, const char *k);
/* Set o[k] to a string "N" as an integer when it is all digits, else the
 * string: the protocol's "name or slot number". */
void dcmd_set_name_or_slot(JsonObject *o, const char *k, const char *v);

/* v with printf format fmt, or "-" when v is NaN, into buf. */
const char *dcmd_fmt(char *buf, size_t n, const char *fmt, double v);
/* Seconds since the epoch of an ISO-8601 time (UTC when no zone); NAN. */
double dcmd_iso_s(const char *iso);
/* --since: "30d", "12h", "90m", "2w", unix seconds, "YYYY-MM-DD" or an
 * ISO-8601 time, as an ISO-8601 UTC string (g_free) or NULL with *error. */
char *dcmd_since_iso(const char *text, GError **error);

#endif
