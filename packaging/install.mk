# Install and package (included by the root Makefile).
#
#   make install [PREFIX=/usr] [DESTDIR=DIR]   the release build, the unit, sysusers/tmpfiles, the
#                                              documented config, the viewer page, the docs
#   make deb                                   build/facescan_<version>_<arch>.deb (dpkg-deb)
#
# Layout (PREFIX=/usr, what the package uses; docs/daemon.md "Install"):
#   $(PREFIX)/bin/facescan, facescand          the CLI (every verb is built into it) and the daemon;
#                                              facescand runs the facescan beside it as its worker
#   $(PREFIX)/lib/systemd/system/facescand.service
#   $(PREFIX)/lib/sysusers.d/facescan.conf, $(PREFIX)/lib/tmpfiles.d/facescan.conf
#   $(SYSCONFDIR)/facescan/facescand.conf      the booth settings + every other key, commented
#   $(PREFIX)/share/facescan/web/              viewer page + the three.js files it loads
#                                              (found from the binary: <bin>/../share/facescan/web)
#   $(PREFIX)/share/doc/facescan/              README.md and docs/; examples/facescand.service.d/
#                                              network.conf, the drop-in viewer_port and the PACS need
# The unit, the binaries' default config path and the docs name /usr/bin and /etc: other
# PREFIX/SYSCONFDIR values are written into the installed unit.
# Not installed: facescan-fw-native and sgbm-baseline (development and bench tools), firmware images.

PREFIX     ?= /usr
SYSCONFDIR ?= /etc
DESTDIR    ?=
UNITDIR    ?= $(PREFIX)/lib/systemd/system
INSTALL_STRIP ?=
# Where the installed binaries come from: the release build (tests/install may point it at the
# sanitizer build when no release build exists).
INSTALL_FROM ?= $(BUILD)/bin
INSTALL_BINS := facescan facescand
# The three.js files the viewer page imports (host/viewer/page/view.html's import map and
# viewer.js, GLTFLoader's own import, the Draco decoder it loads), not the whole npm tree.
WEB_THREE := LICENSE package.json build/three.module.js \
	examples/jsm/controls/OrbitControls.js examples/jsm/loaders/GLTFLoader.js \
	examples/jsm/loaders/DRACOLoader.js examples/jsm/utils/BufferGeometryUtils.js \
	examples/jsm/libs/draco/gltf/draco_decoder.js examples/jsm/libs/draco/gltf/draco_decoder.wasm \
	examples/jsm/libs/draco/gltf/draco_wasm_wrapper.js
WEB_SRC := $(BUILD)/web/node_modules/three
DEB_VERSION ?= $(shell sed -n 's/^\#define FACESCAN_VERSION "\(.*\)"/\1/p' host/common/version.cpp)
DEB_ARCH    := $(shell dpkg --print-architecture 2>/dev/null)
DEB_ROOT    := $(BUILD)/deb/root
DEB_FILE    := $(BUILD)/facescan_$(DEB_VERSION)_$(DEB_ARCH).deb
# dpkg-deb's compressor: xz (Debian's default); tests/install uses gzip for a sanitizer build
# (90 MB: xz takes ~2 min on one core here).
DEB_COMPRESS ?= xz

.PHONY: install deb web-deps

# The installed config: the shipped booth settings, then every other key commented out with its
# meaning and default, straight from facescand --print-config (so it cannot drift from the code).
$(BUILD)/facescand.conf: host/facescand/facescand.conf $(INSTALL_FROM)/facescand packaging/install.mk
	@mkdir -p $(dir $@)
	$(Q){ cat host/facescand/facescand.conf; \
	  printf '\n# ---- every other key, with its default (facescand --print-config). Uncomment to change.\n'; \
	  $(INSTALL_FROM)/facescand --print-config | awk -v set="$$(sed -n 's/^\([a-z_]*\) *=.*/\1/p' host/facescand/facescand.conf)" ' \
	    BEGIN { n = split(set, s, "\n"); for (i = 1; i <= n; i++) skip[s[i]] = 1 } \
	    NR == 1 { next } /^$$/ { blank = 1; next } /^#/ { doc = $$0; next } \
	    { k = $$1; if (k in skip) next; if (blank) print ""; blank = 0; print doc; print "#" $$0 }'; \
	} >$@.tmp && mv $@.tmp $@

web-deps $(WEB_SRC)/build/three.module.js:
	@./tools/install-web-deps.sh web $(BUILD)

install: $(addprefix $(INSTALL_FROM)/,$(INSTALL_BINS)) $(BUILD)/facescand.conf $(WEB_SRC)/build/three.module.js
ifneq ($(MODE),release)
	$(error make install installs the release build; leave MODE unset)
endif
	install -d $(DESTDIR)$(PREFIX)/bin
	install -m755 $(if $(INSTALL_STRIP),-s) $(addprefix $(INSTALL_FROM)/,$(INSTALL_BINS)) $(DESTDIR)$(PREFIX)/bin/
	install -d $(DESTDIR)$(UNITDIR)
	sed -e 's|/usr/bin/|$(PREFIX)/bin/|g' -e 's|/etc/facescan/|$(SYSCONFDIR)/facescan/|g' \
	    -e 's|/usr/share/doc/facescan/|$(PREFIX)/share/doc/facescan/|g' \
	    host/facescand/facescand.service >$(DESTDIR)$(UNITDIR)/facescand.service
	chmod 644 $(DESTDIR)$(UNITDIR)/facescand.service
	install -Dm644 host/facescand/facescand.sysusers $(DESTDIR)$(PREFIX)/lib/sysusers.d/facescan.conf
	install -Dm644 host/facescand/facescand.tmpfiles $(DESTDIR)$(PREFIX)/lib/tmpfiles.d/facescan.conf
	@# An existing config is a site's settings: never overwritten (the new one lands beside it).
	install -d $(DESTDIR)$(SYSCONFDIR)/facescan
	@if [ -e $(DESTDIR)$(SYSCONFDIR)/facescan/facescand.conf ]; then \
	  install -m644 $(BUILD)/facescand.conf $(DESTDIR)$(SYSCONFDIR)/facescan/facescand.conf.new; \
	  echo "install: kept $(DESTDIR)$(SYSCONFDIR)/facescan/facescand.conf; the new default is facescand.conf.new"; \
	else install -m644 $(BUILD)/facescand.conf $(DESTDIR)$(SYSCONFDIR)/facescan/facescand.conf; fi
	install -d $(DESTDIR)$(PREFIX)/share/facescan/web/page
	install -m644 host/viewer/page/* $(DESTDIR)$(PREFIX)/share/facescan/web/page/
	$(foreach f,$(WEB_THREE),install -Dm644 $(WEB_SRC)/$(f) $(DESTDIR)$(PREFIX)/share/facescan/web/node_modules/three/$(f) &&) true
	install -d $(DESTDIR)$(PREFIX)/share/doc/facescan
	install -m644 README.md docs/*.md docs/*.png $(DESTDIR)$(PREFIX)/share/doc/facescan/
	install -Dm644 host/facescand/facescand-network.conf \
		$(DESTDIR)$(PREFIX)/share/doc/facescan/examples/facescand.service.d/network.conf

# The package: `make install` into a staging root, then control files and dpkg-deb. Depends is
# what dpkg-shlibdeps finds the binaries linked against (+ systemd, for sysusers/tmpfiles).
deb: $(addprefix $(INSTALL_FROM)/,$(INSTALL_BINS))
	rm -rf $(BUILD)/deb
	@# -o: the binaries were judged above (make does not pass its own -o down to a sub-make).
	$(MAKE) --no-print-directory $(addprefix -o $(INSTALL_FROM)/,$(INSTALL_BINS)) install \
		DESTDIR=$(abspath $(DEB_ROOT)) PREFIX=/usr SYSCONFDIR=/etc INSTALL_STRIP=1
	install -d $(DEB_ROOT)/DEBIAN $(BUILD)/deb/debian
	printf 'Source: facescan\n\nPackage: facescan\nArchitecture: any\n' >$(BUILD)/deb/debian/control
	cd $(BUILD)/deb && dpkg-shlibdeps -O -e root/usr/bin/facescan -e root/usr/bin/facescand \
		2>shlibdeps.err | sed -n 's/^shlibs:Depends=//p' >depends || { cat shlibdeps.err; exit 1; }
	@test -s $(BUILD)/deb/depends || { echo "deb: dpkg-shlibdeps found no dependencies"; cat $(BUILD)/deb/shlibdeps.err; exit 1; }
	sed -e 's|@VERSION@|$(DEB_VERSION)|' -e 's|@ARCH@|$(DEB_ARCH)|' \
	    -e "s|@DEPENDS@|$$(cat $(BUILD)/deb/depends), systemd|" \
	    -e "s|@SIZE@|$$(du -sk --exclude=DEBIAN $(DEB_ROOT) | cut -f1)|" \
	    packaging/deb/control.in >$(DEB_ROOT)/DEBIAN/control
	echo /etc/facescan/facescand.conf >$(DEB_ROOT)/DEBIAN/conffiles
	install -m755 packaging/deb/postinst packaging/deb/prerm packaging/deb/postrm $(DEB_ROOT)/DEBIAN/
	install -m644 packaging/deb/copyright $(DEB_ROOT)/usr/share/doc/facescan/copyright
	dpkg-deb --root-owner-group -Z$(DEB_COMPRESS) --build $(DEB_ROOT) $(DEB_FILE)
	@echo "deb: $(DEB_FILE)"
