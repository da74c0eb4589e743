/* recon_opts.h - the reconstruction options a client gives for a
 * catalogued run (`reconstruct`'s "options": {"skips": "all", "binary":
 * true, ...}, recon's long option names), checked with the CLI's own code
 * (pipeline_opts_set, pipeline_opts_check) so that a refusal carries the
 * words `specklab recon CUBE` would print.  Kept as compact JSON text from
 * the request to the worker and into the reconstruction's params.
 */
#ifndef SL_DAEMON_RECON_OPTS_H
#define SL_DAEMON_RECON_OPTS_H

#include <json-glib/json-glib.h>

#include "pipeline/pipeline.h"

#define RECON_OPTS_MAX 2048   /* bytes of their JSON text */

/* args' "options" (absent: *json_out ""): each member a string, a number
 * or a boolean.  NULL on success with the normalised text in json_out
 * (every value a string) and, when the options name them, the method
 * (method_out, 16 bytes, else untouched) and projections (else untouched);
 * otherwise the error message (g_free). */
char *recon_opts_read(JsonObject *args, char json_out[RECON_OPTS_MAX], char method_out[16],
                      int *projections);
/* Apply normalised options to po (pipeline_opts_set); SL_EINVAL naming
 * the option when one does not apply. */
int recon_opts_apply(const char *json, pipeline_opts *po, sl_err *err);
/* Member "options" of the open object in b (absent when none). */
void recon_opts_params(const char *json, JsonBuilder *b);

#endif
