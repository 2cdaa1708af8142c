#!/usr/bin/env bash
# Print-Job to bytes at the backend, `halftone serve` against CUPS printing the same files
# through its own filters to the same kind of printer (docs/serve.md, "Speed"):
#   - a one-page 4×6 in shipping label PDF (a Code 128 and a QR code as vector modules, made
#     from zint's module patterns as tests/it/serve.rs makes it) to a 203 dpi ZPL label
#     printer: our `label-203` queue, sent the page as PWG raster (what a phone sends an IPP
#     Everywhere printer; this build takes no PDF) and sent the PDF by CUPS through an IPP
#     Everywhere queue (what a laptop does), against CUPS's Zebra ZPL driver (`ppdc`'s
#     sample.drv, cups-filters' PDF rasteriser, then `rastertolabel`);
#   - a 24 MP JPEG (6000×4000, Grace Hopper scaled up) to a 2 in (384-dot) 203 dpi receipt
#     printer: our `thermal-203` queue (ESC/POS) against CUPS's Zebra CPCL driver on 2 in
#     media (`imagetoraster`, then `rastertolabel`).
# Each job is sent RUNS times (default 5) and timed from the client's submission to the
# job's bytes complete at the backend: for ours, `ipptool` with CUPS's print-job.test, then
# the job's file in the backend folder (put in place by rename, so whole when it appears);
# for CUPS, `lp`, then the job completed (`lpstat`) with its file:// device written.
#
# usage: scripts/serve-bench.sh [OUTDIR]       (default: target/serve-bench)
#   HALFTONE=path/to/halftone (default: target/release/halftone); RUNS=N
# Needs root (cupsd), and Debian's cups, cups-client, cups-ipp-utils, cups-filters,
# cups-ppdc, zint, ghostscript, ffmpeg, python-matplotlib-data.
set -euo pipefail

out=$(realpath -m "${1:-target/serve-bench}")
bin=$(realpath "${HALFTONE:-target/release/halftone}")
runs=${RUNS:-5}
hopper=/usr/share/matplotlib/mpl-data/sample_data/grace_hopper.jpg
for tool in cupsd lpadmin lp lpstat ipptool ppdc zint gs ffmpeg python3; do
    command -v "$tool" >/dev/null || { echo "serve-bench: $tool is missing" >&2; exit 1; }
done
[ -x "$bin" ] || { echo "serve-bench: no binary at $bin (cargo build --release)" >&2; exit 1; }
[ -f "$hopper" ] || { echo "serve-bench: $hopper is missing (python-matplotlib-data)" >&2; exit 1; }
[ "$(id -u)" = 0 ] || { echo "serve-bench: cupsd needs root" >&2; exit 1; }

rm -rf "$out"
mkdir -p "$out"/{ours-label,ours-receipt,cups-out,cups/spool,cups/cache,cups/state,cups/tmp,cups/log,cups/ppd}
chmod 755 "$out" "$out/cups"
chmod 1777 "$out/cups/tmp" "$out/cups-out"

# ---- the two documents ----
python3 - "$out/label.pdf" <<'EOF'
import subprocess, sys
def bits(line):
    return "".join(format(int(h, 16), "08b") for h in line.split())
code = bits(subprocess.run(["zint", "-b", "20", "-d", "1Z999AA10123456784", "--dump"],
                           capture_output=True, text=True, check=True).stdout).rstrip("0")
qr = subprocess.run(["zint", "-b", "58", "--vers=3", "-d",
                     "https://track.example.com/1Z999AA10123456784", "--dump"],
                    capture_output=True, text=True, check=True).stdout.split("\n")
m, q = 0.33 / 25.4 * 72, 0.5 / 25.4 * 72
c = "0 g\n"
c += "".join("%.4f 40 %.4f 60 re\n" % (20.3 + i * m, m) for i, b in enumerate(code) if b == "1")
for y, row in enumerate(l for l in qr if l.strip()):
    for x, b in enumerate(bits(row)[:29]):
        if b == "1":
            c += "%.4f %.4f %.4f %.4f re\n" % (40.2 + x * q, 300.7 - (y + 1) * q, q, q)
c += "f"
objs = ["<< /Type /Catalog /Pages 2 0 R >>", "<< /Type /Pages /Kids [3 0 R] /Count 1 >>",
        "<< /Type /Page /Parent 2 0 R /MediaBox [0 0 288 432] /Contents 4 0 R >>",
        "<< /Length %d >>\nstream\n%s\nendstream" % (len(c), c)]
out, offs = b"%PDF-1.4\n", []
for i, o in enumerate(objs):
    offs.append(len(out))
    out += ("%d 0 obj\n%s\nendobj\n" % (i + 1, o)).encode()
xref = len(out)
out += ("xref\n0 %d\n0000000000 65535 f \n" % (len(objs) + 1)).encode()
out += "".join("%010d 00000 n \n" % o for o in offs).encode()
out += ("trailer\n<< /Size %d /Root 1 0 R >>\nstartxref\n%d\n%%%%EOF\n" % (len(objs) + 1, xref)).encode()
open(sys.argv[1], "wb").write(out)
EOF
# What a phone or a laptop sends an IPP Everywhere printer for the label: the page rasterised
# at the printer's 203 dpi as PWG raster (Ghostscript here; not timed: the client's work).
gs -q -dNOPAUSE -dBATCH -sDEVICE=pwgraster -r203 -sOutputFile="$out/label.pwg" "$out/label.pdf"
ffmpeg -nostdin -hide_banner -loglevel error -y -i "$hopper" -vf scale=6000:4000 -q:v 2 "$out/photo.jpg"

# ---- our server: one queue each ----
servers=()
cleanup() {
    for p in "${servers[@]}"; do kill "$p" 2>/dev/null || true; done
    [ -f "$out/cups/cupsd.pid" ] && kill "$(cat "$out/cups/cupsd.pid")" 2>/dev/null || true
}
trap cleanup EXIT
start_server() { # name preset folder
    "$bin" serve --listen 127.0.0.1:0 --no-dnssd --queue "$1" --preset "$2" \
        --backend "file://$3" >"$out/$1.stdout" 2>"$out/$1.log" &
    servers+=($!)
}
uri_of() { # name -> the queue's URI, once the server says it
    for _ in $(seq 200); do
        grep -o 'ipp://[^ ]*' "$out/$1.stdout" 2>/dev/null && return
        sleep 0.05
    done
    echo "serve-bench: halftone serve for $1 did not start" >&2
    exit 1
}
start_server label label-203 "$out/ours-label"
start_server receipt thermal-203 "$out/ours-receipt"
label_uri=$(uri_of label)
receipt_uri=$(uri_of receipt)

# ---- CUPS: cupsd in a folder of its own, CUPS's label drivers, file:// devices ----
port=$(python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
cat >"$out/cups/cupsd.conf" <<EOF
Listen 127.0.0.1:$port
LogLevel warn
WebInterface No
Browsing No
DefaultAuthType None
<Location />
  Order allow,deny
  Allow all
</Location>
<Policy default>
  <Limit All>
    Order deny,allow
  </Limit>
</Policy>
EOF
c=$out/cups
cat >"$c/cups-files.conf" <<EOF
ServerRoot $c
RequestRoot $c/spool
CacheDir $c/cache
StateDir $c/state
TempDir $c/tmp
ErrorLog $c/log/error_log
AccessLog $c/log/access_log
PageLog $c/log/page_log
DataDir /usr/share/cups
ServerBin /usr/lib/cups
SystemGroup root
FileDevice Yes
EOF
ppdc -d "$c/ppd" /usr/share/cups/drv/sample.drv
cupsd -f -c "$c/cupsd.conf" -s "$c/cups-files.conf" &
echo $! >"$c/cupsd.pid"
export CUPS_SERVER=127.0.0.1:$port
for _ in $(seq 100); do lpstat -r >/dev/null 2>&1 && break; sleep 0.1; done
lpadmin -p zpl -E -v "file://$out/cups-out/label.zpl" -P "$c/ppd/zebra.ppd" -o media=w288h432
lpadmin -p cpcl -E -v "file://$out/cups-out/receipt.cpcl" -P "$c/ppd/zebracpl.ppd"
# And CUPS as our client, the way a laptop prints to us: an IPP Everywhere queue on ours.
# (cupsd can still be busy with the queues above: "Bad file descriptor" was seen once, so a
# few tries.)
for try in 1 2 3 4 5; do
    lpadmin -p everywhere -E -v "$label_uri" -m everywhere && break
    [ "$try" = 5 ] && { echo "serve-bench: lpadmin -m everywhere failed" >&2; exit 1; }
    sleep 1
done

# ---- the runs ----
python3 - "$out" "$runs" "$label_uri" "$receipt_uri" <<'EOF'
import os, statistics, subprocess, sys, time
out, runs, label_uri, receipt_uri = sys.argv[1], int(sys.argv[2]), sys.argv[3], sys.argv[4]

def to_folder(send, folder):
    """Seconds from `send` to a new job file in `folder` (put in place by rename: whole
    when it appears), and its size."""
    seen = set(os.listdir(folder))
    t = time.perf_counter()
    subprocess.run(send, check=True, stdout=subprocess.DEVNULL)
    while True:
        new = [f for f in os.listdir(folder) if f not in seen and not f.startswith(".")]
        if new:
            return time.perf_counter() - t, os.path.getsize(os.path.join(folder, new[0]))
        if time.perf_counter() - t > 300:
            sys.exit("serve-bench: no job reached " + folder)
        time.sleep(0.005)

def ours(uri, doc, folder):
    return to_folder(["ipptool", "-tf", doc, uri, "print-job.test"], folder)

def cups_to_ours(queue, doc, opts, folder):
    return to_folder(["lp", "-d", queue, *opts, doc], folder)

def cups(queue, doc, opts, dest):
    t = time.perf_counter()
    subprocess.run(["lp", "-d", queue, *opts, doc], check=True, stdout=subprocess.DEVNULL)
    while True:
        left = subprocess.run(["lpstat", "-o", queue], capture_output=True, text=True).stdout
        if not left.strip():
            return time.perf_counter() - t, os.path.getsize(dest)
        if time.perf_counter() - t > 300:
            sys.exit("serve-bench: CUPS did not finish on " + queue)
        time.sleep(0.005)

cases = [
    ("label PDF, 4x6 in at 203 dpi", "halftone serve, label-203 (ZPL), sent as PWG raster",
     lambda: ours(label_uri, out + "/label.pwg", out + "/ours-label")),
    ("label PDF, 4x6 in at 203 dpi", "CUPS's IPP Everywhere queue to halftone serve",
     lambda: cups_to_ours("everywhere", out + "/label.pdf", ["-o", "media=na_index-4x6_4x6in"],
                          out + "/ours-label")),
    ("label PDF, 4x6 in at 203 dpi", "CUPS, Zebra ZPL driver",
     lambda: cups("zpl", out + "/label.pdf", [], out + "/cups-out/label.zpl")),
    ("24 MP JPEG to a 384-dot receipt", "halftone serve, thermal-203 (ESC/POS)",
     lambda: ours(receipt_uri, out + "/photo.jpg", out + "/ours-receipt")),
    ("24 MP JPEG to a 384-dot receipt", "CUPS, Zebra CPCL driver, 2 in media",
     lambda: cups("cpcl", out + "/photo.jpg",
                  ["-o", "media=Custom.144x96", "-o", "fit-to-page"],
                  out + "/cups-out/receipt.cpcl")),
]
print("| document | printer | median s | min s | max s | bytes at the backend |")
print("|---|---|---:|---:|---:|---:|")
for doc, who, run in cases:
    times, size = [], 0
    for _ in range(runs):
        s, size = run()
        times.append(s)
    print("| %s | %s | %.3f | %.3f | %.3f | %s |" % (doc, who, statistics.median(times),
          min(times), max(times), format(size, ",")))
EOF
