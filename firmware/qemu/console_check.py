#!/usr/bin/env python3
"""Types at the emulated firmware's console as a person would and checks every reply.

Usage: console_check.py ELF [QEMU]

Starts QEMU (netduinoplus2) with USART1 and USART2 on pseudo-terminals
(`-serial pty`: ttys, as a USB-serial board appears), finds the start of the
console's replies with `ping <token>`, then sends each line of SCRIPT and checks
that the reply ends with `ok` or `error: ...` as expected (and matches a pattern
where one is given). Garbage, control characters, non-ASCII bytes and over-long
lines must be answered with an error and change nothing. Then bursts: twenty
lines pasted at once, a 500-byte paste, a paste far beyond the receive queue,
typing while telemetry streams at 100 rows/s, echo. Every line must get exactly
one reply, in order. Ends with `quit`, which must end QEMU with status 0.
Exit status 0 when every check passed; the failures are listed otherwise.
"""
import os
import re
import select
import subprocess
import sys
import threading
import time
import tty

OK, ERR = "ok", "error"
TIMEOUT = 20.0  # s, longest wait for any reply (generous: the machine may be loaded)

# (line to send (bytes), expected end, regex the whole reply must match or None)
SCRIPT = [
    (b"help", OK, r"goto <mm>"),
    (b"ping abc", OK, r"^pong abc\r\n"),
    (b"ping", OK, r"^pong\r\n"),
    (b"ping a b", ERR, r"usage: ping"),
    (b"status", OK, r"^state=idle faults=none controller=mpc-eso hil=off"),
    (b"get eso.beta1", OK, r"^eso\.beta1 = 30\r\n"),
    (b"get", OK, r"hil\.timeout_ms = 100\r\n"),
    (b"frobnicate", ERR, r"unknown command"),
    (b"xyzzy 1 2 3", ERR, r"unknown command"),
    (b"set eso.beta1", ERR, r"usage: set"),
    (b"set eso.beta1 abc", ERR, r"not a number"),
    (b"set eso.beta1 -1", ERR, r"out of range"),
    (b"set eso.beta1 1e999", ERR, None),
    (b"set mpc_eso.np 8.5", ERR, r"whole number"),
    (b"set mpc.np 1", ERR, r"horizon"),
    (b"set no.such 1", ERR, r"unknown setting"),
    (b"get eso.beta1", OK, r"= 30\r\n"),
    (b"set\x01 eso.beta1 5", ERR, r"invalid character"),
    ("get eso.b\u00e9ta1".encode(), ERR, r"invalid character"),
    (b"set eso.beta1 " + b"9" * 100, ERR, r"line too long"),
    (b"x" * 500, ERR, r"line too long"),
    (b"get eso.beta1", OK, r"= 30\r\n"),
    (b"stat\x08\x08atus", OK, r"^state=idle"),
    (b"set eso.beta1 35", OK, None),
    (b"get eso.beta1", OK, r"= 35\r\n"),
    (b"set mpc_eso.rw 300", OK, None),
    (b"controller", OK, r"^mpc-eso\r\n"),
    (b"controller lqr", ERR, r"usage"),
    (b"controller pid", OK, None),
    (b"store", OK, None),
    (b"defaults", OK, None),
    (b"get eso.beta1", OK, r"= 30\r\n"),
    (b"load", OK, None),
    (b"get eso.beta1", OK, r"= 35\r\n"),
    (b"controller", OK, r"^pid\r\n"),
    (b"preset fast", OK, None),
    (b"get mpc_eso.ts_s", OK, r"= 0\.01\r\n"),
    (b"preset paper", OK, None),
    (b"goto 10", ERR, r"not armed"),
    (b"stop", ERR, r"not armed"),
    (b"clear", ERR, r"no fault"),
    (b"arm", OK, None),
    (b"arm", ERR, r"disarm first"),
    (b"set pid.kp 3", ERR, r"disarm first"),
    (b"hil on", ERR, r"disarm first"),
    (b"goto 500", ERR, r"stroke"),
    (b"goto 10", OK, None),
    (b"status", OK, r"state=running"),
    (b"sine 10 0.5", OK, None),
    (b"sine 80 0.5", ERR, r"amplitude"),
    (b"sine 10 50", ERR, r"frequency"),
    (b"stop", OK, None),
    (b"status", OK, r"state=armed"),
    (b"telemetry on 5", ERR, r"decimation"),
    (b"telemetry on 20", OK, None),
    (b"telemetry off", OK, None),
    (b"disarm", OK, None),
    (b"status", OK, r"state=idle"),
    (b"hil on", OK, None),
    (b"status", OK, r"hil=on"),
    (b"goto 10", ERR, None),
    (b"hil off", OK, None),
    (b"echo on", OK, None),
    (b"echo off", OK, None),
    (b"fault", OK, r"^faults=none\r\nlink good=0 corrupt=0 lost=0 late=0 skipped=0\r\n"),
]

ROW = re.compile(rb"^\d+\.\d{3},")
END = re.compile(rb"^(ok|error: .*)$")


class Console:
    """The console pty: lines in, replies out, the telemetry stream set apart."""

    def __init__(self, path):
        self.fd = os.open(path, os.O_RDWR | os.O_NOCTTY)
        tty.setraw(self.fd)
        self.buf = b""
        self.stream = []  # telemetry lines (metadata, header, rows)

    def send(self, data):
        view = memoryview(data)
        while view:
            n = os.write(self.fd, view)
            view = view[n:]

    def line(self, until):
        """The next non-stream line (without CR LF), or None at `until`."""
        while True:
            i = self.buf.find(b"\n")
            if i >= 0:
                raw, self.buf = self.buf[:i + 1], self.buf[i + 1:]
                line = raw.rstrip(b"\r\n")
                if not line:
                    continue
                if line.startswith(b"#") or line.startswith(b"t_s,") or ROW.match(line):
                    self.stream.append(line)
                    continue
                return line
            left = until - time.time()
            if left <= 0:
                return None
            r, _, _ = select.select([self.fd], [], [], min(left, 0.5))
            if r:
                self.buf += os.read(self.fd, 4096)

    def reply(self, timeout=TIMEOUT):
        """The lines of one reply up to its `ok` / `error: ...` (bytes)."""
        until = time.time() + timeout
        lines = []
        while True:
            line = self.line(until)
            if line is None:
                raise TimeoutError("no reply end; got %r" % lines[-5:])
            lines.append(line)
            if END.match(line):
                return lines

    def handshake(self):
        """Skip whatever came before: wait for the pong of a fresh token."""
        start = time.time()
        k = 0
        while time.time() - start < TIMEOUT:
            k += 1
            token = b"check%d-%d" % (os.getpid(), k)
            self.send(b"\r\nping " + token + b"\r\n")
            until = time.time() + 1.0
            seen = False
            while True:
                line = self.line(until)
                if line is None:
                    break
                if line == b"pong " + token:
                    seen = True
                elif seen and line == b"ok":
                    return k
        raise TimeoutError("the console never answered ping")


def start_qemu(elf, qemu):
    cmd = [qemu, "-machine", "netduinoplus2", "-nographic", "-monitor", "none",
           "-semihosting-config", "enable=on,target=native", "-icount", "shift=3,sleep=on",
           "-serial", "pty", "-serial", "pty", "-kernel", elf]
    q = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    ptys = {}
    while len(ptys) < 2:
        line = q.stdout.readline()
        if not line:
            raise RuntimeError("QEMU named no ptys: " + q.stderr.read().decode(errors="replace"))
        m = re.match(rb"char device redirected to (\S+) \(label serial(\d)\)", line)
        if m:
            ptys[int(m.group(2))] = m.group(1).decode()
    # Keep draining QEMU's stdout (defmt frames) so that it never blocks.
    threading.Thread(target=lambda: q.stdout.read(), daemon=True).start()
    return q, ptys


class Checker:
    def __init__(self, con):
        self.con = con
        self.failures = 0
        self.checks = 0

    def check(self, good, what, detail=None):
        self.checks += 1
        print(("PASS" if good else "FAIL"), what)
        if not good:
            self.failures += 1
            if detail is not None:
                print("   got:", detail)

    def one(self, line, want, pattern):
        self.con.send(line + b"\r\n")
        lines = self.con.reply()
        last = lines[-1].decode(errors="replace")
        text = (b"\r\n".join(lines) + b"\r\n").decode(errors="replace")
        good = last == "ok" if want == OK else last.startswith("error: ")
        if good and pattern is not None:
            good = re.search(pattern, text) is not None
        shown = line if len(line) < 60 else line[:40] + b"... (%d bytes)" % len(line)
        self.check(good, "%r -> %s" % (shown, last), None if good else text)
        if not good and "fault latched" in last:
            self.con.send(b"fault\r\n")
            print("   fault:", b" | ".join(self.con.reply()).decode(errors="replace"))

    def burst(self, what, lines, expect):
        """Send `lines` in one write; `expect(i, reply_lines)` judges reply i."""
        self.con.send(b"".join(l + b"\r\n" for l in lines))
        bad = []
        for i in range(len(lines)):
            try:
                r = self.con.reply()
            except TimeoutError as e:
                bad.append("reply %d of %d missing: %s" % (i + 1, len(lines), e))
                break
            if not expect(i, r):
                bad.append("reply %d: %r" % (i + 1, r))
        self.check(not bad, "%s: %d lines, %d replies in order" % (what, len(lines), len(lines)),
                   bad[:3])


def main():
    elf = sys.argv[1]
    qemu = sys.argv[2] if len(sys.argv) > 2 else "qemu-system-arm"
    q, ptys = start_qemu(elf, qemu)
    con = Console(ptys[0])
    c = Checker(con)
    try:
        tries = con.handshake()
        print("console on %s answered ping (try %d)" % (ptys[0], tries))
        for line, want, pattern in SCRIPT:
            c.one(line, want, pattern)
            if line == b"telemetry on 20":
                # The stream follows the reply: the run-log header, then rows.
                until = time.time() + TIMEOUT
                while len(con.stream) < 6 and time.time() < until:
                    con.line(time.time() + 0.2)
                head = [l.decode(errors="replace") for l in con.stream]
                ok = (len(head) >= 6 and head[0] == "# dca-log v1"
                      and head[3].startswith("t_s,ref_m,vcmd_mps,xi_m,xo_m")
                      and head[4].startswith("0.000,") and head[5].startswith("0.020,"))
                c.check(ok, "telemetry stream is a run log", head[:6])
        bursts(c, con)
        con.send(b"quit\r\n")
        status = q.wait(timeout=TIMEOUT)
        c.check(status == 0, "quit ends QEMU with status 0", status)
    except TimeoutError as e:
        c.check(False, "a reply came in time", str(e))
    finally:
        if q.poll() is None:
            q.kill()
    print("%d passed, %d failed" % (c.checks - c.failures, c.failures))
    return 1 if c.failures else 0


def bursts(c, con):
    # Twenty lines pasted at once, of every kind of reply.
    kinds = [(b"get eso.beta1", rb"^eso\.beta1 = \d+$", "ok"),
             (b"status", rb"^state=idle", "ok"),
             (b"help", rb"goto", "ok"),
             (b"frobnicate", None, "error"),
             (b"ping k", rb"^pong k$", "ok")]
    lines, want = [], []
    for i in range(20):
        line, pat, end = kinds[i % len(kinds)]
        lines.append(line)
        want.append((pat, end))

    def judge(i, r):
        pat, end = want[i]
        if not r[-1].decode().startswith(end):
            return False
        return pat is None or any(re.search(pat, l) for l in r)
    c.burst("twenty lines pasted at once", lines, judge)

    # A 500-byte paste of short lines: 50 x "ping NNN\r\n".
    lines = [b"ping %03d" % i for i in range(50)]
    assert sum(len(l) + 2 for l in lines) == 500
    c.burst("a 500-byte paste", lines, lambda i, r: r == [b"pong %03d" % i, b"ok"])

    # Far beyond the 2 KiB receive queue: 60 lines of 80 characters (4 860 bytes).
    # Each gets one reply, its own or a discard, in order.
    lines = [(b"ping %02d" % i).ljust(80, b"x") for i in range(60)]
    n_own = [0]

    def own_or_discarded(i, r):
        if r == [b"pong " + lines[i][5:], b"ok"]:
            n_own[0] += 1
            return True
        return r == [b"error: input queue full, line discarded"]
    c.burst("4 860 bytes pasted at once", lines, own_or_discarded)
    c.check(n_own[0] >= 25, "the first lines of it fit the queue (%d of 60 answered)" % n_own[0])
    c.one(b"ping after", OK, r"^pong after\r\n")
    c.one(b"fault", OK, r"^faults=none\r\n")

    # Typing while telemetry streams at 100 rows/s: every line answered, no row lost.
    c.one(b"arm", OK, None)
    con.stream.clear()
    c.one(b"telemetry on 10", OK, None)
    for ch in b"status\r\n":
        con.send(bytes([ch]))
        time.sleep(0.005)
    c.check(con.reply()[-1] == b"ok", "typed `status` answered while streaming")
    c.burst("twenty lines pasted while streaming", [b"get eso.beta1"] * 20,
            lambda i, r: r[-1] == b"ok" and r[0].startswith(b"eso.beta1 = "))
    c.one(b"goto 20", OK, None)
    # A second of the stream in the emulator's time (which runs slower than the
    # wall clock on a loaded machine): wait for the rows, not for the clock.
    until = time.time() + TIMEOUT
    while sum(1 for l in con.stream if ROW.match(l)) < 120 and time.time() < until:
        con.line(time.time() + 0.2)
    c.one(b"telemetry off", OK, None)
    rows = [l for l in con.stream if ROW.match(l)]
    stamps = [int(l.split(b",")[0].replace(b".", b"")) for l in rows]
    steps = set(b - a for a, b in zip(stamps, stamps[1:]))
    c.check(len(rows) >= 120 and steps == {10},
            "the stream stayed whole: %d rows, steps %s ms" % (len(rows), sorted(steps)))
    c.one(b"disarm", OK, None)

    # Echo: typed characters come back before the reply.
    c.one(b"echo on", OK, None)
    con.send(b"ping e\r\n")
    r = con.reply()
    c.check(r == [b"ping e", b"pong e", b"ok"], "echo, then the reply", r)
    c.one(b"echo off", OK, None)


if __name__ == "__main__":
    sys.exit(main())
