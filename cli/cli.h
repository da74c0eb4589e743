/* cli.h - the specklab command's subcommands and shared helpers. */
#ifndef SL_CLI_H
#define SL_CLI_H

#include <glib.h>
#include <json-glib/json-glib.h>

/* Each subcommand gets argv with argv[0] = "specklab SUBCOMMAND" and
 * returns the process exit status: 0 ok, 1 failure, 2 usage error. */
int cmd_sim(int argc, char **argv);
int cmd_mask(int argc, char **argv);
int cmd_stage(int argc, char **argv);
int cmd_camera(int argc, char **argv);
int cmd_devices(int argc, char **argv);
int cmd_recon(int argc, char **argv);
/* `specklab recon CUBE` as one process of a run split over several
 * (pipeline.h, pipeline_share; NULL: cmd_recon): rank 0 writes the
 * outputs, the others only add their frames' sums. */
struct pipeline_share;
int cmd_recon_shared(int argc, char **argv, const struct pipeline_share *share);
int cmd_compare(int argc, char **argv);
int cmd_binary(int argc, char **argv);
int cmd_oifits(int argc, char **argv);
int cmd_bench(int argc, char **argv);

/* Parse "N" or "WxH" into width/height; FALSE with a message on error. */
gboolean cli_parse_size(const char *text, int *w, int *h, GError **error);
/* Parse the options of a subcommand; on error print it with the usage
 * hint and return FALSE. */
gboolean cli_parse(GOptionContext *ctx, int *argc, char ***argv);
/* Print a JSON object built with b to stdout, one line. */
void cli_print_json(JsonBuilder *b);
/* Add member k to the object being built: a string, an integer, or a
 * number (null when not finite, since JSON has no NaN). */
void cli_json_str(JsonBuilder *b, const char *k, const char *v);
void cli_json_int(JsonBuilder *b, const char *k, gint64 v);
void cli_json_num(JsonBuilder *b, const char *k, double v);
/* Wall-clock seconds (monotonic). */
double cli_now_s(void);
/* Peak resident set size of this process in MB. */
double cli_peak_rss_mb(void);

#endif
