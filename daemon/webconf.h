/* webconf.h - where specklabd serves its web page (web.h): the [web]
 * group's listen address, and the same from the command line.
 *
 *   listen = HOST:PORT    HOST an IPv4 or IPv6 literal ([::1]:8080) or
 *                         "localhost" (127.0.0.1); PORT 0..65535, 0 picks
 *                         a free port (the READY line and the log say
 *                         which).  Absent or empty: no web page.
 *   allow_remote = no     A HOST that is not a loopback address
 *                         (127.0.0.0/8, ::1) is refused unless yes: the
 *                         page has no authentication, so serving it
 *                         beyond this machine is a decision written down,
 *                         never a default (the daemon logs a warning
 *                         when it does).
 *   max_connections = 32  HTTP connections served at once (1..1024);
 *                         more are answered 503 and closed.
 * Names are never resolved: no DNS lookup decides what the page is
 * exposed to.  Pure C (no GIO), so fuzz_config links it.
 */
#ifndef SL_DAEMON_WEBCONF_H
#define SL_DAEMON_WEBCONF_H

#include "status.h"
#include "config.h"

/* Parse "HOST:PORT" (also "[V6]:PORT") into a numeric host (owned, no
 * brackets) and port; *loopback tells whether the host is a loopback
 * address.  SL_EINVAL with a message naming what (the caller prefixes the
 * key or option). */
int webconf_parse(const char *text, char **host, int *port, int *loopback, sl_err *err);

/* Set the listener (config_load's [web], or --web): text NULL or "" turns
 * the page off.  A non-loopback host without allow_remote is SL_EINVAL
 * naming `what` (e.g. "config [web] listen", "--web") and the key or
 * option that allows it. */
int webconf_set(config *c, const char *what, const char *text, int allow_remote,
                const char *allow_name, sl_err *err);

#endif
