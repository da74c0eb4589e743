/* jsonmode.h - with --json, every outcome on stdout is one JSON object.
 *
 * The subcommands print their result object on success and a plain
 * message on stderr when they fail.  A program reading --json output must
 * not have to scrape stderr, so main() wraps a --json command in a
 * capture: stdout and stderr go to temporary files while it runs, then
 *   - success: stdout is replayed unchanged;
 *   - failure: the result object (when the command printed one, e.g. a
 *     bench experiment with a failed run) gains an "error" member, or a
 *     new object {"error": ...} is printed:
 *       {"error": {"command": "recon", "status": 2, "kind": "usage",
 *                  "message": "<the last line the command printed>",
 *                  "messages": [every stderr line]}}
 *     kind is "usage" for exit status 2, "failure" for 1.
 * stderr is always replayed, so a person still reads the message.
 * Cost: the command's output is held until it ends (it prints one object
 * at the end anyway); a progress bar is not drawn (stderr is not a TTY).
 */
#ifndef SL_JSONMODE_H
#define SL_JSONMODE_H

#include <stdio.h>

typedef struct jsonmode {
    int active;
    int saved_out, saved_err;  /* the real stdout/stderr, dup'ed */
    FILE *out, *err;           /* the captures */
} jsonmode;

/* Does argv (after the command name) ask for --json? */
int jsonmode_wanted(int argc, char **argv);
/* Start capturing; on any failure to set up, jm stays inactive and the
 * command runs with plain output (a warning says so). */
void jsonmode_begin(jsonmode *jm);
/* Stop capturing and print as the header says; returns status. */
int jsonmode_end(jsonmode *jm, const char *command, int status);

#endif
