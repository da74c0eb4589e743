# mk/install.mk - make man, install and uninstall (included by Makefile).
#
# GNU conventions: PREFIX (default /usr/local) and DESTDIR (staging root,
# empty for a real install).  specklab (and specklab-mpi when the build
# has MPI) goes to PREFIX/bin, specklabd to
# PREFIX/sbin (a system daemon, section 8), the man pages to
# PREFIX/share/man, the unit to PREFIX/lib/systemd/system, PROTOCOL.md and
# the example configuration to PREFIX/share/doc/specklab.  The system
# configuration is /etc/specklab/specklabd.conf for PREFIX=/usr and
# PREFIX/etc/specklab otherwise; it is written only when absent, so an
# edited one survives a reinstall and an uninstall.  Mocks, tests and
# benchmarks are never installed.

PREFIX     ?= /usr/local
DESTDIR    ?=
BINDIR     := $(PREFIX)/bin
SBINDIR    := $(PREFIX)/sbin
MANDIR     := $(PREFIX)/share/man
DOCDIR     := $(PREFIX)/share/doc/specklab
UNITDIR    := $(PREFIX)/lib/systemd/system
SYSCONFDIR := $(if $(filter /usr,$(PREFIX)),/etc,$(PREFIX)/etc)
MAN_OUT    := $(BUILD)/man
MAN_PAGES  := $(MAN_OUT)/specklab.1 $(MAN_OUT)/specklabd.8 $(MAN_OUT)/specklabd.conf.5

# The installed configuration: absolute paths where the unit lets the
# daemon write (StateDirectory, RuntimeDirectory).
SYSTEM_CONF_SED := -e 's|^data_dir=.*|data_dir=/var/lib/specklab|' \
                   -e 's|^\#socket=.*|socket=/run/specklab/specklabd.sock|'
UNIT_SED := -e 's|@SBINDIR@|$(SBINDIR)|g' -e 's|@DOCDIR@|$(DOCDIR)|g' \
            -e 's|@SYSCONFDIR@|$(SYSCONFDIR)|g'

.PHONY: man install uninstall
man: $(MAN_PAGES)

$(MAN_PAGES): $(BIN)/specklab $(BIN)/specklabd man/specklab.h2m man/specklabd.h2m \
              man/specklabd.conf.5.head man/specklabd.conf.5.tail \
              daemon/specklabd.conf.example scripts/man-pages
	@command -v help2man >/dev/null || scripts/install-deps
	scripts/man-pages $(BIN) $(MAN_OUT)

install: $(BIN)/specklab $(BIN)/specklabd $(MAN_PAGES) $(MPI_BIN)
	install -d $(DESTDIR)$(BINDIR) $(DESTDIR)$(SBINDIR) $(DESTDIR)$(MANDIR)/man1 \
	    $(DESTDIR)$(MANDIR)/man5 $(DESTDIR)$(MANDIR)/man8 $(DESTDIR)$(DOCDIR) \
	    $(DESTDIR)$(UNITDIR) $(DESTDIR)$(SYSCONFDIR)/specklab
	install -m 0755 $(BIN)/specklab $(DESTDIR)$(BINDIR)/specklab
	install -m 0755 $(BIN)/specklabd $(DESTDIR)$(SBINDIR)/specklabd
	$(if $(MPI_BIN),install -m 0755 $(MPI_BIN) $(DESTDIR)$(BINDIR)/specklab-mpi)
	install -m 0644 $(MAN_OUT)/specklab.1 $(DESTDIR)$(MANDIR)/man1/specklab.1
	install -m 0644 $(MAN_OUT)/specklabd.8 $(DESTDIR)$(MANDIR)/man8/specklabd.8
	install -m 0644 $(MAN_OUT)/specklabd.conf.5 $(DESTDIR)$(MANDIR)/man5/specklabd.conf.5
	install -m 0644 daemon/PROTOCOL.md daemon/specklabd.conf.example $(DESTDIR)$(DOCDIR)/
	sed $(UNIT_SED) daemon/specklabd.service >$(DESTDIR)$(UNITDIR)/specklabd.service
	chmod 0644 $(DESTDIR)$(UNITDIR)/specklabd.service
	@if [ -e $(DESTDIR)$(SYSCONFDIR)/specklab/specklabd.conf ]; then \
	    echo "kept $(DESTDIR)$(SYSCONFDIR)/specklab/specklabd.conf (exists)"; \
	else \
	    sed $(SYSTEM_CONF_SED) daemon/specklabd.conf.example \
	        >$(DESTDIR)$(SYSCONFDIR)/specklab/specklabd.conf && \
	    chmod 0644 $(DESTDIR)$(SYSCONFDIR)/specklab/specklabd.conf; \
	fi

# The configuration stays (it may hold the lab's edits), like the data.
uninstall:
	rm -f $(DESTDIR)$(BINDIR)/specklab $(DESTDIR)$(BINDIR)/specklab-mpi $(DESTDIR)$(SBINDIR)/specklabd \
	    $(DESTDIR)$(MANDIR)/man1/specklab.1 $(DESTDIR)$(MANDIR)/man8/specklabd.8 \
	    $(DESTDIR)$(MANDIR)/man5/specklabd.conf.5 $(DESTDIR)$(UNITDIR)/specklabd.service \
	    $(DESTDIR)$(DOCDIR)/PROTOCOL.md $(DESTDIR)$(DOCDIR)/specklabd.conf.example
	-rmdir $(DESTDIR)$(DOCDIR) 2>/dev/null
