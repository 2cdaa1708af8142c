#!/usr/bin/env bash
# Array jobs on a real Slurm cluster: a one-node cluster started by hand under a temp folder
# (munged, slurmctld, slurmd; no systemd, no cgroups: proctrack/linuxproc, task/affinity),
# then a 3-task array of `halftone batch --shard auto` over 30 inputs (3 broken), one task
# cancelled mid-run and resubmitted alone, another requeued after it finished. Checks that
# every output exists once, byte-identical to an unsharded run, that the exit statuses and
# the merged report say what happened, and stops the daemons it started.
#
# Needs Debian's slurmctld slurmd slurm-client munge (installed by .ci/run) and root (the
# daemons run as root here). Where the cluster cannot start, this says so and fails.
# Usage: scripts/slurm-test.sh [path/to/halftone]   (default target/release/halftone)
# KEEP=1 keeps the temp folder (logs, reports) for a look afterwards.
set -uo pipefail
cd "$(dirname "$0")/.."
HALFTONE="$(realpath "${1:-target/release/halftone}")"
START=$SECONDS
passed=0
failed=0

ok() { passed=$((passed + 1)); echo "ok: $*"; }
bad() { failed=$((failed + 1)); echo "FAILED: $*"; }
check() { # check "what" command...
  local what=$1; shift
  if "$@"; then ok "$what"; else bad "$what"; fi
}
finish() {
  echo "slurm: $passed passed, $failed failed ($((SECONDS - START)) s)"
  [ "$failed" -eq 0 ] && [ "$passed" -gt 0 ]
}
cannot() {
  echo "slurm: the cluster cannot start: $*"
  failed=$((failed + 1))
  finish
  exit 1
}

for tool in munged slurmctld slurmd sbatch squeue scontrol scancel sinfo python3; do
  command -v "$tool" >/dev/null 2>&1 || cannot "$tool is not installed (apt-get install slurmctld slurmd slurm-client munge)"
done
[ -x "$HALFTONE" ] || cannot "$HALFTONE is not built (cargo build --release)"
[ "$(id -u)" = 0 ] || cannot "the daemons are started as root here; run as root"

T="$(mktemp -d /tmp/halftone-slurm.XXXXXX)"
chmod 755 "$T"
PIDS=()
stop() {
  # Only the daemons this script started, by their process ids.
  for pid in "${PIDS[@]}"; do kill "$pid" 2>/dev/null; done
  for pid in "${PIDS[@]}"; do
    for _ in $(seq 50); do kill -0 "$pid" 2>/dev/null || break; sleep 0.1; done
    kill -9 "$pid" 2>/dev/null
  done
  if [ "${KEEP:-0}" = 1 ]; then echo "slurm: kept $T"; else rm -rf "$T"; fi
}
trap stop EXIT

# ---- munge --------------------------------------------------------------------------------
mkdir -p "$T/munge"
chmod 700 "$T/munge"
head -c 1024 /dev/urandom >"$T/munge/munge.key"
chmod 400 "$T/munge/munge.key"
munged --force --foreground --key-file="$T/munge/munge.key" --socket="$T/munge/munge.socket" \
  --pid-file="$T/munge/munged.pid" --log-file="$T/munge/munged.log" \
  --seed-file="$T/munge/munged.seed" >"$T/munge/stdout.log" 2>&1 &
PIDS+=($!)
for _ in $(seq 50); do [ -S "$T/munge/munge.socket" ] && break; sleep 0.1; done
[ -S "$T/munge/munge.socket" ] || cannot "munged did not start: $(tail -3 "$T/munge/munged.log" "$T/munge/stdout.log" 2>/dev/null)"

# ---- slurmctld and slurmd -----------------------------------------------------------------
NODE="$(hostname -s)"
CPUS="$(nproc)"
CTLD_PORT=$((20000 + RANDOM % 20000))
SLURMD_PORT=$((CTLD_PORT + 1))
mkdir -p "$T/state" "$T/spool" "$T/logs" "$T/reports"
export SLURM_CONF="$T/slurm.conf"
cat >"$SLURM_CONF" <<EOF
ClusterName=halftone-ci
SlurmctldHost=$NODE(127.0.0.1)
SlurmctldPort=$CTLD_PORT
SlurmdPort=$SLURMD_PORT
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
AuthInfo=socket=$T/munge/munge.socket
CredType=cred/munge
StateSaveLocation=$T/state
SlurmdSpoolDir=$T/spool
SlurmctldPidFile=$T/slurmctld.pid
SlurmdPidFile=$T/slurmd.pid
SlurmctldLogFile=$T/slurmctld.log
SlurmdLogFile=$T/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/affinity
SchedulerType=sched/backfill
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
MpiDefault=none
ReturnToService=2
JobRequeue=1
KillWait=5
MinJobAge=600
NodeName=$NODE NodeAddr=127.0.0.1 CPUs=$CPUS State=UNKNOWN
PartitionName=ci Nodes=$NODE Default=YES MaxTime=INFINITE State=UP
EOF
slurmctld -D -c -f "$SLURM_CONF" >"$T/slurmctld.stdout" 2>&1 &
PIDS+=($!)
slurmd -D -f "$SLURM_CONF" -N "$NODE" >"$T/slurmd.stdout" 2>&1 &
PIDS+=($!)
state=""
for _ in $(seq 150); do
  state="$(sinfo -h -n "$NODE" -o %T 2>/dev/null)"
  [ "$state" = idle ] && break
  sleep 0.2
done
if [ "$state" != idle ]; then
  tail -5 "$T/slurmctld.log" "$T/slurmd.log" "$T/slurmctld.stdout" "$T/slurmd.stdout" 2>/dev/null
  cannot "node $NODE is '${state:-unknown}', not idle, after 30 s"
fi
ok "one-node cluster up: node $NODE idle with $CPUS CPUs after $((SECONDS - START)) s ($(slurmctld -V))"

# ---- inputs and the unsharded reference ---------------------------------------------------
IN="$T/in"
python3 - "$IN" <<'EOF'
import os, sys
d = sys.argv[1]
os.makedirs(d)
w = h = 320
for i in range(27):
    data = bytes(((x * 255) // w + (y * (i + 1)) // 9) % 256 for y in range(h) for x in range(w))
    with open(os.path.join(d, f"page{i:02}.pgm"), "wb") as f:
        f.write(b"P5\n%d %d\n255\n" % (w, h) + data)
# Broken inputs named so that they sort 1st, 3rd and 30th: shards 1 and 3 of 3 meet one,
# shard 2 none (so both exit statuses, 0 and 3, are seen).
open(os.path.join(d, "a-empty.pgm"), "wb").close()
with open(os.path.join(d, "page01-torn.pgm"), "wb") as f:
    f.write(b"P5\n320 320\n255\n" + bytes(1000))
with open(os.path.join(d, "zz-notes.png"), "w") as f:
    f.write("this is text, not a picture\n")
EOF
NFILES=$(find "$IN" -type f | wc -l)
ARGS=(--format pbm -m dbs --skip-existing -q)
"$HALFTONE" batch "$IN" -o "$T/ref" "${ARGS[@]}" --report "$T/ref.jsonl" 2>"$T/ref.log"
ref_rc=$?
check "unsharded reference run: exit 3 (done, 3 inputs rejected), $(find "$T/ref" -type f | wc -l) outputs" \
  test "$ref_rc" = 3

# ---- the array job ------------------------------------------------------------------------
OUT="$T/out"
cat >"$T/job.sh" <<EOF
#!/bin/bash
#SBATCH --job-name=halftone
#SBATCH --cpus-per-task=1
#SBATCH --output=$T/logs/%A_%a.log
# SHARD comes from the submission: auto for the array, auto/3 for a task resubmitted alone.
"$HALFTONE" batch "$IN" -o "$OUT" ${ARGS[*]} --shard "\$SHARD" \\
  --report "$T/reports/task-\$SLURM_ARRAY_TASK_ID.jsonl"
rc=\$?
echo "\$SLURM_ARRAY_TASK_ID \$SLURM_JOB_ID \$rc \${SLURM_RESTART_COUNT:-0}" >>"$T/status.txt"
exit \$rc
EOF
JOB=$(sbatch --parsable --array=1-3 --export=ALL,SHARD=auto "$T/job.sh") || cannot "sbatch refused the array"
echo "submitted array job $JOB (tasks 1-3, --shard auto)"

# The files of shard 2 of 3: the 2nd, 5th, 8th, ... of the sorted list.
mapfile -t SHARD2 < <(find "$IN" -type f -printf '%f\n' | LC_ALL=C sort | awk 'NR % 3 == 2')
shard2_done() {
  local n=0 f
  for f in "${SHARD2[@]}"; do [ -f "$OUT/${f%.*}.pbm" ] && n=$((n + 1)); done
  echo "$n"
}
wait_jobs() {
  for _ in $(seq 600); do
    [ -z "$(squeue -h -o %i 2>/dev/null)" ] && return 0
    sleep 0.2
  done
  return 1
}

# Cancel task 2 once it has written an output, while it still has files to do.
for _ in $(seq 600); do
  [ "$(shard2_done)" -ge 1 ] && break
  sleep 0.1
done
scancel "${JOB}_2"
for _ in $(seq 100); do
  st="$(scontrol show job "${JOB}_2" 2>/dev/null | grep -o 'JobState=[A-Z_]*' | head -1)"
  [ "$st" = JobState=CANCELLED ] && break
  sleep 0.1
done
partial=$(shard2_done)
check "task 2 cancelled mid-run ($st) with $partial of its ${#SHARD2[@]} files written" \
  test "$st" = JobState=CANCELLED -a "$partial" -lt "${#SHARD2[@]}"
wait_jobs || bad "the array did not finish within 120 s"
leftover=$(find "$OUT" "$T/reports" -name '.*.tmp' | wc -l)
check "SIGTERM from scancel left no temp file ($leftover)" [ "$leftover" = 0 ]

# Resubmitted alone, plain auto sees an array of one task and refuses; auto/3 maps it back.
sbatch --wait --array=2 --export=ALL,SHARD=auto "$T/job.sh" >/dev/null
alone=$(find "$T/logs" -name '*_2.log' -newer "$T/job.sh" -print0 | xargs -0 grep -h 'auto/N' | head -1)
check "a task resubmitted alone with plain --shard auto is refused: ${alone:-no message}" \
  test -n "$alone"
RESUB=$(sbatch --parsable --array=2 --export=ALL,SHARD=auto/3 "$T/job.sh")
wait_jobs || bad "the resubmitted task did not finish"
check "task 2 resubmitted alone (job $RESUB, --array=2, --shard auto/3) finished its shard" \
  test "$(shard2_done)" = "${#SHARD2[@]}"

# Requeue a finished task: it runs again and writes nothing twice.
stamp() { find "$OUT" -type f -printf '%P %i %T@\n' | LC_ALL=C sort; }
before="$(stamp)"
scontrol requeue "${JOB}_1" || bad "scontrol requeue ${JOB}_1 refused"
# A requeued job waits before it is eligible again; start it now.
scontrol update JobId="${JOB}_1" StartTime=now >/dev/null 2>&1
for _ in $(seq 300); do
  [ "$(awk -v j="${JOB}_1" '$1 == 1 && $4 >= 1' "$T/status.txt" | wc -l)" -ge 1 ] && break
  sleep 0.2
done
wait_jobs
requeued=$(awk '$1 == 1 && $4 >= 1 {print $3}' "$T/status.txt" | tail -1)
check "task 1 requeued (restart 1, exit ${requeued:-none}) wrote nothing again" \
  test -n "$requeued" -a "$before" = "$(stamp)"

# ---- what the array made ------------------------------------------------------------------
same=$(diff -r "$T/ref" "$OUT" >/dev/null && echo yes || echo no)
nout=$(find "$OUT" -type f | wc -l)
check "every output once and byte-identical to the unsharded run: $nout files, same: $same" \
  test "$same" = yes -a "$nout" = "$(find "$T/ref" -type f | wc -l)"

# Exit statuses: 3 for a shard with a rejected input, 0 for one without, 1 for the refused
# plain auto (the cancelled run records none: its shell was stopped with it).
mapfile -t broken_shards < <(find "$IN" -type f -printf '%f\n' | LC_ALL=C sort \
  | awk '/^(a-empty|page01-torn|zz-notes)\./ {print (NR - 1) % 3 + 1}' | sort -u)
codes_ok=yes
refused=0
while read -r task _ rc _; do
  want=0
  for k in "${broken_shards[@]}"; do [ "$k" = "$task" ] && want=3; done
  if [ "$rc" = 1 ] && [ "$task" = 2 ]; then
    refused=$((refused + 1))
  elif [ "$rc" != "$want" ]; then
    codes_ok=no
  fi
done <"$T/status.txt"
[ "$refused" = 1 ] || codes_ok=no
check "exit statuses (task:status): 3 for shards with rejected inputs (${broken_shards[*]}), 0 otherwise, 1 for the refused run: $(awk '{printf "%s:%s ", $1, $3}' "$T/status.txt")" \
  test "$codes_ok" = yes

merge="$("$HALFTONE" batch report merge "$T"/reports/task-*.jsonl -o "$T/merged.jsonl")"
merge_rc=$?
echo "$merge" | sed 's/^/  merge: /'
check "merged report: $NFILES files, 3 rejected, nothing missing or twice (exit $merge_rc)" \
  test "$merge_rc" = 3 -a "$(wc -l <"$T/merged.jsonl")" = "$NFILES" \
  -a -z "$(echo "$merge" | grep -E '^(missing|duplicated|failed)')"

tasks=$(wc -l <"$T/status.txt")
echo "slurm: array $JOB: 3 tasks + 2 resubmissions + 1 requeue ($tasks task runs recorded), $NFILES inputs, $nout outputs"
finish
