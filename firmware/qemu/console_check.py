#!/usr/bin/env python3
"""Types at the emulated firmware's console as a person would and checks every reply.

Usage: console_check.py ELF [QEMU]

Starts QEMU (netduinoplus2) with USART1 and USART2 on TCP sockets, waits for the
banner, then sends each line of SCRIPT and checks that the reply ends with `ok`
or `error: ...` as expected (and matches a pattern where one is given). Garbage,
control characters, non-ASCII bytes and over-long lines must be answered with an
error and change nothing. Ends with `quit`, which must end QEMU with status 0.
Exit status 0 when every check passed; the failures are listed otherwise.
"""
import re
import socket
import subprocess
import sys
import time

OK, ERR = "ok", "error"

# (line to send (bytes), expected end, regex the whole reply must match or None)
SCRIPT = [
    (b"help", OK, r"goto <mm>"),
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
    (b"fault", OK, r"^faults=none\r\nlink good=0 corrupt=0 lost=0 late=0\r\n"),
]


def listen():
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    s.listen(1)
    return s


def main():
    elf = sys.argv[1]
    qemu = sys.argv[2] if len(sys.argv) > 2 else "qemu-system-arm"
    c1, c2 = listen(), listen()
    cmd = [qemu, "-machine", "netduinoplus2", "-nographic", "-monitor", "none",
           "-semihosting-config", "enable=on,target=native", "-icount", "shift=3,sleep=on",
           "-chardev", f"socket,id=c1,host=127.0.0.1,port={c1.getsockname()[1]},nodelay=on",
           "-chardev", f"socket,id=c2,host=127.0.0.1,port={c2.getsockname()[1]},nodelay=on",
           "-serial", "chardev:c1", "-serial", "chardev:c2", "-kernel", elf]
    q = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    c1.settimeout(10)
    c2.settimeout(10)
    con, _ = c1.accept()
    _link, _ = c2.accept()
    con.settimeout(10)
    buf = b""

    def read_until(pred):
        nonlocal buf
        start = time.time()
        while not pred(buf):
            if time.time() - start > 10:
                raise TimeoutError(repr(buf[-200:]))
            buf += con.recv(4096)

    def reply_end(b):
        return re.search(rb"(^|\r\n)(ok|error: [^\r\n]*)\r\n", b) is not None

    failures = 0
    try:
        read_until(lambda b: b"ready" in b and b.endswith(b"\r\n"))
        print(buf.decode(errors="replace").strip())
        buf = b""
        for line, want, pattern in SCRIPT:
            con.sendall(line + b"\r\n")
            read_until(reply_end)
            m = re.search(rb"(^|\r\n)(ok|error: [^\r\n]*)\r\n", buf)
            reply, buf = buf[: m.end()].decode(errors="replace"), buf[m.end():]
            last = m.group(2).decode()
            good = last == "ok" if want == OK else last.startswith("error: ")
            if good and pattern is not None:
                good = re.search(pattern, reply) is not None
            shown = line if len(line) < 60 else line[:40] + b"... (%d bytes)" % len(line)
            print(("PASS" if good else "FAIL"), shown, "->", last)
            if not good:
                failures += 1
                print("   reply was:", repr(reply))
            if line == b"telemetry on 20":
                # The stream follows the reply: the run-log header, then rows.
                read_until(lambda b: b.count(b"\r\n") >= 8)
                text = buf.decode()
                head = text.split("\r\n")
                ok = (head[0] == "# dca-log v1" and head[3].startswith("t_s,ref_m,vcmd_mps,xi_m,xo_m")
                      and re.match(r"^0\.000,", head[4]) and re.match(r"^0\.020,", head[5]))
                print(("PASS" if ok else "FAIL"), "telemetry stream is a run log")
                failures += 0 if ok else 1
                con.sendall(b"telemetry off\r\n")
                read_until(lambda b: b.endswith(b"ok\r\n"))
                buf = b""
        con.sendall(b"quit\r\n")
        status = q.wait(timeout=10)
        if status != 0:
            failures += 1
            print("FAIL quit: QEMU exit status", status, q.stderr.read().decode())
    finally:
        if q.poll() is None:
            q.kill()
    total = len(SCRIPT) + 2
    print(f"{total - failures} passed, {failures} failed")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
