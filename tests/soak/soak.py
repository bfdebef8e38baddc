#!/usr/bin/env python3
"""facescand soak with injected faults (issue 12, "Prove it"; docs/daemon.md, "Soak").

facescand (its own process) + the firmware core on the native board behind a pty
(facescan-fw-native) + simulated cameras + the real `facescan recon` worker run N scans back to
back, requested over the control socket (armed, then the firmware's DEBUG_BUTTON) or by the
booth button (SIGUSR1 to the firmware). A seeded injector adds, at random and logged: share
removed (its bind mount unmounted: the mount point stays, the marker goes), share read-only,
share full (a small tmpfs filled), MCU link killed or MCU reset (SIGUSR2: reset pin) mid-scan,
a camera's frames delayed or dropped (config sim_camera_faults: the simulated sensor), the
recon worker killed, facescand kill -9ed (restarted as systemd would).

At the end every scan facescand accepted must be on the share exactly once, byte-identical to
what the worker wrote (its hash is logged by a wrapper around `facescan recon`) and to the
sha256 manifest of the scan's metadata, or reported failed with its reason (and, when it failed
after capture, its capture kept in <spool>/captures/); nothing lost, nothing twice, no partial
file visible; facescand's RSS and fd count flat. Exit 0 only then.

Needs root (tmpfs and bind mounts). Exit 77 when it cannot run here.
"""
import argparse
import glob
import hashlib
import json
import os
import random
import re
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time

KINDS = ["share_removed", "share_readonly", "share_full", "mcu_link_killed", "mcu_reset",
         "camera_frames_delayed", "camera_frames_dropped", "worker_killed", "facescand_killed"]
ID = r"([0-9a-f]{12})"
SETTLE_US = 200000  # not the firmware's default (20000): a reset MCU must be given it again


class Soak:
    def __init__(self, a):
        self.a = a
        self.bin = os.path.abspath(a.bin)
        self.rng = random.Random(a.seed)
        self.T = tempfile.mkdtemp(prefix="facescan-soak-", dir=a.tmp)
        self.share = self.T + "/share"
        self.backing = self.T + "/backing"
        self.spool = self.T + "/spool"
        self.sock = self.T + "/sock"
        self.tty = self.T + "/tty"
        self.faults_file = self.T + "/camera-faults"
        self.hashes = self.T + "/worker-hashes"
        self.daemon_log = self.T + "/daemon.log"
        self.fault_log = open(self.T + "/faults.log", "w")
        self.daemon = None
        self.fw = None
        self.mounted = []
        self.injected = {k: 0 for k in KINDS}
        self.missed = {}
        self.daemon_starts = 0
        self.fw_starts = 0
        self.requested = 0
        self.refused = {}
        self.accepted = []      # scan ids facescand answered or logged
        self.samples = []       # (pid, rss_kb, fds)
        self.timers = []
        self.lock = threading.Lock()

    # ---- logging -------------------------------------------------------------------------
    def note(self, what):
        line = "%s %s" % (time.strftime("%H:%M:%S"), what)
        self.fault_log.write(line + "\n")
        self.fault_log.flush()
        if self.a.verbose:
            print(line, flush=True)

    # ---- the share: a small tmpfs, bind-mounted at share/ ---------------------------------
    def setup_share(self):
        os.makedirs(self.backing)
        os.makedirs(self.share)
        size_mb = self.a.share_mb
        subprocess.run(["mount", "-t", "tmpfs", "-o", "size=%dm" % size_mb, "soak", self.backing], check=True)
        self.mounted.append(self.backing)
        os.makedirs(self.backing + "/share")
        open(self.backing + "/share/.facescan-share", "w").close()
        self.mount_share()

    def mount_share(self, ro=False):
        subprocess.run(["mount", "--bind", self.backing + "/share", self.share], check=True)
        self.mounted.append(self.share)
        if ro:
            subprocess.run(["mount", "-o", "remount,bind,ro", self.share], check=True)

    def share_mounted(self):
        return os.path.exists(self.share + "/.facescan-share")

    def unmount_share(self):
        subprocess.run(["umount", "-l", self.share], check=True)
        self.mounted.remove(self.share)

    def fill_share(self):
        st = os.statvfs(self.backing)
        free = st.f_bavail * st.f_frsize
        with open(self.backing + "/filler", "wb") as f:  # beside the share's folder, not in it
            try:
                f.write(b"\0" * max(0, free - 64 * 1024))
            except OSError:
                pass

    def unfill_share(self):
        if os.path.exists(self.backing + "/filler"):
            os.unlink(self.backing + "/filler")

    # ---- the firmware and the daemon ------------------------------------------------------
    def start_fw(self):
        self.fw = subprocess.Popen([self.bin + "/facescan-fw-native", "--link", self.tty],
                                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        self.fw_starts += 1
        for _ in range(50):
            if os.path.exists(self.tty):
                return
            time.sleep(0.1)
        raise RuntimeError("facescan-fw-native did not start")

    def fw_alive(self):
        return self.fw is not None and self.fw.poll() is None

    def write_config(self):
        worker = self.T + "/worker.sh"
        with open(worker, "w") as f:
            # The real worker, and a record of what it reconstructed (byte-identical check).
            f.write("#!/bin/sh\n"
                    "\"%s/facescan\" \"$@\"\nrc=$?\n"
                    "[ \"$rc\" -gt 128 ] && kill -s $((rc - 128)) $$\n"
                    "out=\nprev=\nfor a in \"$@\"; do [ \"$prev\" = -o ] && out=$a; prev=$a; done\n"
                    "[ \"$rc\" -eq 0 ] && sha256sum \"$out\" >>\"%s\"\n"
                    "exit $rc\n" % (self.bin, self.hashes))
        os.chmod(worker, 0o755)
        conf = {
            "mode": "booth", "share_dir": self.share, "share_marker": ".facescan-share",
            "spool_dir": self.spool, "socket_path": self.sock, "serial_device": self.tty,
            "camera_backend": "simulated", "sim_scale_percent": self.a.scale,
            "sim_camera_faults": self.faults_file, "recon_backend": "pipeline",
            "recon_worker": worker, "min_free_mb": 1, "spool_retry_ms": 300,
            "mcu_timeout_ms": 1500, "capture_timeout_ms": self.a.capture_timeout_ms,
            "output_thumbnail": "false", "projector_settle_us": SETTLE_US,
            "recon_memory_mb": self.a.recon_memory_mb,
        }
        with open(self.T + "/facescand.conf", "w") as f:
            for k, v in conf.items():
                f.write("%s = %s\n" % (k, v))

    def start_daemon(self):
        log = open(self.daemon_log, "a")
        self.daemon = subprocess.Popen([self.bin + "/facescand", "--config", self.T + "/facescand.conf"],
                                       stdout=log, stderr=log)
        log.close()
        self.daemon_starts += 1
        for _ in range(300):
            if self.daemon.poll() is not None:
                raise RuntimeError("facescand exited at start (%s)" % self.daemon.returncode)
            if self.request({"cmd": "status"}, timeout=2) is not None:
                return
            time.sleep(0.1)
        raise RuntimeError("facescand did not answer")

    def daemon_alive(self):
        return self.daemon is not None and self.daemon.poll() is None

    def supervise(self):
        """Restart what the injector killed, as systemd (Restart=on-failure) and a re-plugged
        cable would."""
        if not self.fw_alive():
            self.start_fw()
            self.note("restart: facescan-fw-native")
        if not self.daemon_alive():
            self.start_daemon()
            self.note("restart: facescand")

    # ---- the control socket ---------------------------------------------------------------
    def connect(self, timeout):
        s = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        s.settimeout(timeout)
        s.connect(self.sock)
        return s

    def request(self, req, timeout=5):
        try:
            s = self.connect(timeout)
            s.sendall((json.dumps(req) + "\n").encode())
            line = s.makefile("r").readline()
            s.close()
            return json.loads(line) if line else None
        except (OSError, ValueError):
            return None

    # ---- the daemon's log: what it says happened to each scan -----------------------------
    def log_text(self):
        with open(self.daemon_log, errors="replace") as f:
            return f.read()

    def outcomes(self):
        text = self.log_text()
        out = {}
        for m in re.finditer(r"scan %s: (?:\[3/3\] delivered|spooled scan delivered|delivered before the daemon)" % ID, text):
            out[m.group(1)] = ("delivered", "")
        for m in re.finditer(r"scan %s: \[3/3\] spooled" % ID, text):
            out.setdefault(m.group(1), ("spooled", "waiting for the share"))
        for m in re.finditer(r"scan %s: failed while (\w+): (.*)" % ID, text):
            out.setdefault(m.group(1), ("failed", "%s: %s" % (m.group(2), m.group(3))))
        for m in re.finditer(r"scan %s: interrupted while (\w+)" % ID, text):
            out.setdefault(m.group(1), ("failed", "interrupted while %s (daemon killed)" % m.group(2)))
        for m in re.finditer(r"scan %s: no button press within" % ID, text):
            out.setdefault(m.group(1), ("failed", "disarmed: no press"))
        return out

    def started_ids(self):
        return set(re.findall(r"scan %s: (?:armed|\[1/3\] capturing)" % ID, self.log_text()))

    # ---- faults -----------------------------------------------------------------------------
    def procs(self):
        """(pid, ppid, argv) of every process."""
        out = []
        for p in os.listdir("/proc"):
            if not p.isdigit():
                continue
            try:
                with open("/proc/%s/stat" % p) as f:
                    ppid = int(f.read().rsplit(")", 1)[1].split()[1])
                with open("/proc/%s/cmdline" % p, "rb") as f:
                    argv = f.read().split(b"\0")
                out.append((int(p), ppid, [x.decode(errors="replace") for x in argv if x]))
            except (OSError, IndexError, ValueError):
                pass
        return out

    def worker_pids(self):
        if not self.daemon_alive():
            return []
        ps = self.procs()
        mine = {self.daemon.pid}
        changed = True
        while changed:
            changed = False
            for pid, ppid, _ in ps:
                if ppid in mine and pid not in mine:
                    mine.add(pid)
                    changed = True
        return [pid for pid, _, argv in ps if pid in mine and len(argv) > 1 and
                argv[0].endswith("/facescan") and argv[1] == "recon"]

    def later(self, delay, fn):
        t = threading.Timer(delay, fn)
        t.daemon = True
        t.start()
        self.timers.append(t)

    def inject_before(self, kind):
        """Faults that hold through the scan; cleared after it."""
        self.injected[kind] += 1
        if kind == "share_removed":
            self.unmount_share()
        elif kind == "share_readonly":
            subprocess.run(["mount", "-o", "remount,bind,ro", self.share], check=True)
        elif kind == "share_full":
            self.fill_share()
        elif kind == "camera_frames_delayed":
            ms = self.rng.choice([300, 800, self.a.capture_timeout_ms + 1500])
            cam = self.rng.randrange(4)
            with open(self.faults_file, "w") as f:
                f.write("delay %d %d\n" % (cam, ms))
            kind += " (camera %d, %d ms)" % (cam, ms)
        elif kind == "camera_frames_dropped":
            cam = self.rng.randrange(4)
            with open(self.faults_file, "w") as f:
                f.write("drop %d\n" % cam)
            kind += " (camera %d)" % cam
        self.note("inject: " + kind)

    def clear_faults(self):
        if not self.share_mounted() and self.share not in self.mounted:
            self.mount_share()
            self.note("clear: share mounted again")
        if self.share in self.mounted and not os.access(self.share, os.W_OK):
            subprocess.run(["mount", "-o", "remount,bind,rw", self.share], check=True)
            self.note("clear: share writable again")
        if os.path.exists(self.backing + "/filler"):
            self.unfill_share()
            self.note("clear: share emptied of the filler")
        if os.path.exists(self.faults_file):
            os.unlink(self.faults_file)
            self.note("clear: camera faults off")

    def inject_during(self, kind):
        """Faults that strike mid-scan, from a timer; counted when they strike."""
        if kind == "mcu_link_killed":
            delay = self.rng.uniform(0.0, 0.3)
        elif kind == "mcu_reset":
            delay = self.rng.uniform(0.0, 0.3)
        elif kind == "facescand_killed":
            delay = 0
            target = self.rng.choice(["armed", "capturing", "reconstructing", "writing", "writing"])
        else:
            delay = 0

        def strike():
            if kind == "mcu_link_killed" and self.fw_alive():
                self.fw.kill()
                self.injected[kind] += 1
                self.note("inject: mcu_link_killed (facescan-fw-native kill -9) at +%.2f s" % delay)
                time.sleep(self.rng.uniform(0.5, 2.0))
                with self.lock:
                    if not self.fw_alive():
                        self.fw.wait()
                        self.start_fw()
                        self.note("clear: MCU link back")
            elif kind == "mcu_reset" and self.fw_alive():
                self.fw.send_signal(signal.SIGUSR2)
                self.injected[kind] += 1
                self.note("inject: mcu_reset (reset pin) at +%.2f s" % delay)
            elif kind == "facescand_killed":
                # In the stage drawn (writing twice as often: the spool's commit and delivery).
                end = time.time() + self.a.scan_s * 3
                while time.time() < end and self.daemon_alive():
                    st = self.request({"cmd": "status"}, timeout=1)
                    if st and st.get("state") == target:
                        if target == "writing":
                            time.sleep(self.rng.uniform(0.0, 0.08))
                        self.daemon.kill()
                        self.injected[kind] += 1
                        self.note("inject: facescand_killed (kill -9) while %s" % target)
                        return
                    time.sleep(0.01)
                self.missed[kind] = self.missed.get(kind, 0) + 1
                self.note("inject: facescand_killed: never saw %s (missed)" % target)
            elif kind == "worker_killed":
                for _ in range(int(self.a.scan_s * 40)):
                    pids = self.worker_pids()
                    if pids:
                        time.sleep(self.rng.uniform(0.0, 0.5))
                        hit = False
                        for p in pids:
                            try:
                                os.kill(p, signal.SIGKILL)
                                hit = True
                            except OSError:
                                pass
                        if hit:
                            self.injected[kind] += 1
                        else:
                            self.missed[kind] = self.missed.get(kind, 0) + 1
                        self.note("inject: worker_killed (facescan recon pid %s, kill -9)" % pids)
                        return
                    time.sleep(0.05)
                self.missed[kind] = self.missed.get(kind, 0) + 1
                self.note("inject: worker_killed: no worker ran (missed)")
        self.later(delay, strike)

    # ---- one scan ---------------------------------------------------------------------------
    def wait_outcome(self, sid, deadline):
        while time.time() < deadline:
            if sid in self.outcomes():
                return True
            with self.lock:
                if not self.daemon_alive():
                    rc = self.daemon.wait()
                    self.start_daemon()
                    self.note("restart: facescand (exit %s)" % rc)
            time.sleep(0.2)
        return False

    def scan_by_socket(self, n):
        self.requested += 1
        patient = "SOAK-%04d" % n
        r = self.request({"cmd": "scan", "patient": patient}, timeout=5)
        if not r or not r.get("ok"):
            why = (r or {}).get("error", "no answer (daemon down)")
            self.refused[why] = self.refused.get(why, 0) + 1
            self.note("scan %d: request refused: %s" % (n, why))
            return None
        sid = r["scan_id"]
        self.request({"cmd": "button"})  # DEBUG_BUTTON: the firmware's own press starts it
        return sid

    def scan_by_button(self, n):
        self.requested += 1
        before = self.started_ids()
        self.fw.send_signal(signal.SIGUSR1)
        for _ in range(40):
            new = self.started_ids() - before
            if new:
                return new.pop()
            time.sleep(0.1)
        self.refused["press ignored"] = self.refused.get("press ignored", 0) + 1
        self.note("scan %d: press ignored" % n)
        return None

    def wait_idle(self, timeout):
        end = time.time() + timeout
        while time.time() < end:
            with self.lock:
                if not self.daemon_alive():
                    rc = self.daemon.wait()
                    self.start_daemon()
                    self.note("restart: facescand (exit %s)" % rc)
            st = self.request({"cmd": "status"}, timeout=2)
            if st and st.get("state") == "idle":
                return True
            time.sleep(0.2)
        return False

    def sample(self):
        if not self.daemon_alive():
            return
        pid = self.daemon.pid
        try:
            with open("/proc/%d/status" % pid) as f:
                rss = int(re.search(r"VmRSS:\s+(\d+)", f.read()).group(1))
            # The fewest of a few reads a tenth of a second apart: `idle` can still catch the
            # daemon with a client's socket not yet reaped or the spool's queue directory open for
            # a moment (seen: 13 fds at one read, 9 at the next); a leak is a floor that rises.
            fds = len(os.listdir("/proc/%d/fd" % pid))
            for _ in range(4):
                time.sleep(0.1)
                fds = min(fds, len(os.listdir("/proc/%d/fd" % pid)))
            self.samples.append((pid, rss, fds))
            self.note("sample: facescand pid %d RSS %d KiB, %d fds" % (pid, rss, fds))
        except (OSError, AttributeError):
            pass

    def plan(self):
        """Which fault strikes which scan: every kind at least once, then at random."""
        n = self.a.scans
        plan = [None] * n
        slots = list(range(1, n))
        self.rng.shuffle(slots)
        kinds = list(KINDS)
        for k in kinds:
            if slots:
                plan[slots.pop()] = k
        for i in slots:
            if self.rng.random() < self.a.fault_rate:
                plan[i] = self.rng.choice(kinds)
        return plan

    def run(self):
        self.setup_share()
        os.makedirs(self.spool)
        self.write_config()
        self.start_fw()
        self.start_daemon()
        plan = self.plan()
        t0 = time.time()
        for n in range(self.a.scans):
            kind = plan[n]
            with self.lock:
                self.supervise()
            self.wait_idle(60)
            if kind in ("share_removed", "share_readonly", "share_full", "camera_frames_delayed",
                        "camera_frames_dropped"):
                self.inject_before(kind)
            by = "button" if self.rng.random() < self.a.button_share else "socket"
            sid = self.scan_by_button(n) if by == "button" else self.scan_by_socket(n)
            if kind in ("mcu_link_killed", "mcu_reset", "worker_killed", "facescand_killed"):
                self.inject_during(kind)
            if sid:
                self.accepted.append(sid)
                ok = self.wait_outcome(sid, time.time() + self.a.scan_timeout_s)
                o = self.outcomes().get(sid, ("no outcome yet", ""))
                self.note("scan %d: %s by %s: %s %s" % (n, sid, by, o[0], o[1]))
                if not ok:
                    self.note("scan %d: %s: no outcome within %d s" % (n, sid, self.a.scan_timeout_s))
            for t in self.timers:
                t.join()
            self.timers = []
            with self.lock:
                self.supervise()
            self.wait_idle(60)
            self.sample()
            self.clear_faults()
            if self.a.verbose or n % 10 == 9:
                print("soak: %d/%d scans, %.0f s" % (n + 1, self.a.scans, time.time() - t0), flush=True)
        # Everything back; the spool drains to the share.
        self.clear_faults()
        with self.lock:
            self.supervise()
        end = time.time() + 120
        while time.time() < end:
            st = self.request({"cmd": "status"}, timeout=2)
            if st and st.get("spool_pending") == 0 and st.get("state") == "idle":
                break
            time.sleep(0.3)
        self.sample()
        self.elapsed = time.time() - t0

    # ---- the verdict --------------------------------------------------------------------------
    def verify(self):
        hashes = set()
        if os.path.exists(self.hashes):
            with open(self.hashes) as f:
                hashes = {line.split()[0] for line in f if line.strip()}
        outcomes = self.outcomes()
        accepted = set(self.accepted) | self.started_ids()
        visible = [p for p in glob.glob(self.share + "/**", recursive=True)
                   if os.path.isfile(p) and not os.path.basename(p).startswith(".")]
        hidden = [p for p in glob.glob(self.share + "/**/.*", recursive=True)
                  if os.path.isfile(p) and os.path.basename(p) != ".facescan-share"]
        by_id = {}
        stray = []
        for p in visible:
            m = re.match(r"^\d{8}T\d{6}Z_%s[._]" % ID, os.path.basename(p))
            if m:
                by_id.setdefault(m.group(1), []).append(p)
            else:
                stray.append(p)
        r = {"delivered": 0, "failed": {}, "lost": [], "duplicated": [], "half_written": [],
             "not_reconstructed_bytes": [], "capture_not_kept": [], "failed_but_on_share": [],
             "unknown_on_share": [], "stray": stray, "hidden_temp": hidden, "wrong_timing": []}
        for sid in sorted(accepted | set(by_id)):
            files = by_id.get(sid, [])
            o = outcomes.get(sid)
            if sid not in accepted:
                r["unknown_on_share"].append(sid)
                continue
            if not files:
                if o and o[0] == "failed":
                    reason = re.sub(r"[0-9a-f]{12}|\d+", "N", o[1].split(";")[0])[:90]
                    r["failed"][reason] = r["failed"].get(reason, 0) + 1
                    # Captured, then lost to the worker, the spool or the daemon's death: the capture stays.
                    after_capture = re.match(r"(reconstructing|writing|interrupted while (reconstructing|writing))", o[1])
                    if after_capture and not glob.glob(self.spool + "/captures/*_" + sid + "/capture.json"):
                        r["capture_not_kept"].append(sid)
                else:
                    r["lost"].append(sid)
                continue
            if o and o[0] == "failed":
                r["failed_but_on_share"].append(sid)
            bases = {re.sub(r"(_thumb)?\.[a-z]+$", "", os.path.basename(p)) for p in files}
            dirs = {os.path.dirname(p) for p in files}
            if len(bases) > 1 or len(dirs) > 1:
                r["duplicated"].append(sid)
                continue
            base = os.path.join(dirs.pop(), bases.pop())
            try:
                with open(base + ".json") as f:
                    meta = json.load(f)
                manifest = {e["file"]: e["sha256"] for e in meta["manifest"]}
            except (OSError, ValueError, KeyError, TypeError):
                r["half_written"].append(sid)
                continue
            names = {os.path.basename(p) for p in files} - {os.path.basename(base) + ".json"}
            good = names == set(manifest)
            for name, sha in manifest.items():
                try:
                    with open(os.path.join(os.path.dirname(base), name), "rb") as f:
                        good = good and hashlib.sha256(f.read()).hexdigest() == sha
                except OSError:
                    good = False
            if not good:
                r["half_written"].append(sid)
                continue
            # The firmware fired with the configured timing (set again after every MCU reset),
            # its 4 shutters in one write.
            tr = meta.get("trigger_report") or {}
            ticks = tr.get("step_ticks") or [0, 0]
            if ticks[1] - ticks[0] != SETTLE_US or tr.get("shutters_in_lockstep") is not True:
                r["wrong_timing"].append(sid)
                continue
            with open(base + ".drc", "rb") as f:
                if hashlib.sha256(f.read()).hexdigest() not in hashes:
                    r["not_reconstructed_bytes"].append(sid)
                    continue
            r["delivered"] += 1
        r["accepted"] = len(accepted)
        # Every failure has a fault behind it: the share's faults fail nothing (spooled), the
        # others at most the scan they strike.
        r["failed_total"] = sum(r["failed"].values())
        r["failing_faults"] = sum(v for k, v in self.injected.items() if not k.startswith("share_"))
        return r

    def report(self, r):
        lines = []
        w = lines.append
        w("soak: seed %d, %d scans requested (%d accepted), %.0f s, facescand started %d times, "
          "firmware %d times" % (self.a.seed, self.requested, r["accepted"], self.elapsed,
                                 self.daemon_starts, self.fw_starts))
        w("")
        w("| faults injected | count |")
        w("|---|---|")
        for k in KINDS:
            w("| %s | %d%s |" % (k, self.injected[k],
                                 " (+%d missed: the scan ended first)" % self.missed[k] if self.missed.get(k) else ""))
        w("| total | %d |" % sum(self.injected.values()))
        w("")
        w("| outcome | count |")
        w("|---|---|")
        w("| delivered (on the share once, bytes = worker's = manifest) | %d |" % r["delivered"])
        for why, c in sorted(r["failed"].items(), key=lambda x: -x[1]):
            w("| failed: %s | %d |" % (why.replace("|", "/"), c))
        for why, c in sorted(self.refused.items()):
            w("| not started: %s | %d |" % (why, c))
        for key, label in (("lost", "lost"), ("duplicated", "duplicated"), ("half_written", "half-written / damaged visible"),
                           ("not_reconstructed_bytes", "bytes not the worker's"),
                           ("wrong_timing", "fired without the configured timing"),
                           ("failed_but_on_share", "reported failed but on the share"),
                           ("capture_not_kept", "failed after capture, capture not kept"),
                           ("unknown_on_share", "on the share, never accepted"), ("stray", "stray files on the share"),
                           ("hidden_temp", "temp files left on the share (hidden)")):
            v = r[key]
            w("| %s | %d%s |" % (label, len(v), (" " + " ".join(os.path.basename(x) for x in v[:5])) if v else ""))
        w("")
        w("failed %d, faults that can fail a scan %d%s" % (r["failed_total"], r["failing_faults"],
          "" if r["failed_total"] <= r["failing_faults"] else ": MORE FAILURES THAN FAULTS"))
        if self.samples:
            first, last = self.samples[0], self.samples[-1]
            w("")
            w("facescand RSS / fds: first %d KiB / %d (pid %d), last %d KiB / %d (pid %d)" %
              (first[1], first[2], first[0], last[1], last[2], last[0]))
            # The longest-lived process, after its first 3 scans (buffers, malloc arenas of the
            # scan threads, the simulator's scene): its own baseline and its last sample.
            lives = {}
            for s in self.samples:
                lives.setdefault(s[0], []).append(s)
            pid, ss = max(lives.items(), key=lambda x: len(x[1]))
            # RSS swings by a scan's buffers (~100 MB at 25 %): the peaks of the first and the
            # second half of its life are compared, not two single samples.
            base = ss[min(3, len(ss) - 1)]
            steady = ss[3:] if len(ss) > 4 else ss
            half = max(1, len(steady) // 2)
            peak1, peak2 = max(x[1] for x in steady[:half]), max(x[1] for x in steady[half:] or steady[:half])
            w("longest-lived facescand (pid %d, %d scans): after 3 scans RSS %d KiB / %d fds, last %d KiB / %d fds; "
              "RSS peak first half %d KiB, second half %d KiB; fds max %d" %
              (pid, len(ss), base[1], base[2], ss[-1][1], ss[-1][2], peak1, peak2, max(x[2] for x in ss)))
            self.flat = (max(x[2] for x in steady) <= base[2] + 2 and peak2 <= peak1 * 1.1 + 16 * 1024 and
                         all(s[2] <= 16 for s in self.samples))
            w("flat: %s" % ("yes" if self.flat else "NO"))
        else:
            self.flat = False
        return "\n".join(lines)

    def cleanup(self):
        for t in self.timers:
            t.cancel()
        for p in (self.daemon, self.fw):
            if p is not None and p.poll() is None:
                p.kill()
                p.wait()
        for m in reversed(list(self.mounted)):
            subprocess.run(["umount", "-l", m])
        if self.a.keep:
            print("soak: kept " + self.T)
        else:
            shutil.rmtree(self.T, ignore_errors=True)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--bin", default=os.environ.get("FACESCAN_BIN", "build/bin"))
    ap.add_argument("--scans", type=int, default=200)
    ap.add_argument("--seed", type=int, default=int(os.environ.get("SOAK_SEED", "12")))
    ap.add_argument("--scale", type=int, default=25, help="sim_scale_percent")
    ap.add_argument("--fault-rate", type=float, default=0.4, help="share of scans with a fault")
    ap.add_argument("--button-share", type=float, default=0.4, help="share of scans started by the button")
    ap.add_argument("--scan-s", type=float, default=6.0, help="about how long a scan takes")
    ap.add_argument("--scan-timeout-s", type=int, default=180)
    ap.add_argument("--capture-timeout-ms", type=int, default=2000)
    ap.add_argument("--recon-memory-mb", type=int, default=4096,
                    help="recon_memory_mb (0 for a sanitizer build: its shadow needs terabytes)")
    ap.add_argument("--share-mb", type=int, default=0, help="share tmpfs size (0: from --scans)")
    ap.add_argument("--tmp", default=None)
    ap.add_argument("--table", default=None, help="also write the table to this file")
    ap.add_argument("--keep", action="store_true")
    ap.add_argument("-v", "--verbose", action="store_true")
    a = ap.parse_args()
    if a.share_mb == 0:
        a.share_mb = 16 + a.scans // 3
    if os.geteuid() != 0:
        print("SKIP: the soak mounts a tmpfs share (needs root)", file=sys.stderr)
        return 77
    if not os.access(os.path.join(a.bin, "facescan-fw-native"), os.X_OK):
        print("SKIP: %s/facescan-fw-native not built" % a.bin, file=sys.stderr)
        return 77
    s = Soak(a)
    try:
        s.run()
        r = s.verify()
        table = s.report(r)
    finally:
        s.cleanup()
    print(table)
    if a.table:
        with open(a.table, "w") as f:
            f.write(table + "\n")
    bad = (r["lost"] or r["duplicated"] or r["half_written"] or r["not_reconstructed_bytes"] or r["wrong_timing"] or
           r["failed_but_on_share"] or r["capture_not_kept"] or r["unknown_on_share"] or r["stray"] or
           not s.flat or r["failed_total"] > r["failing_faults"] or r["delivered"] == 0)
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
