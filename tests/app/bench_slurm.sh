#!/usr/bin/env bash
# `mcslam bench --executor slurm` on a real one-node Slurm cluster on 127.0.0.1, from Debian's
# slurm-wlm and munge: a munge key and slurm.conf generated in a temporary folder, munged,
# slurmctld and slurmd started by this script as the user running it (root or not) and stopped
# when it ends, also on failure (trap); their logs are kept in OUT/cluster-logs. Then:
#  1. a submission to a partition that does not exist is refused with sbatch's message;
#  2. a bench whose run hangs (its camera.yaml is a FIFO nobody writes) is submitted with
#     a 1-minute time limit: Slurm kills the task, and the collect job reports the run as failed
#     with its Slurm state TIMEOUT and its log; the run is then fixed and resubmitted alone;
#  3. a small bench (two synthetic sequences, two configurations, two runs, sequential) runs
#     through Slurm and on this machine at the same time (while the task of 2. waits for its
#     limit); the collected tables must match the local ones (the accuracy of sequential runs is
#     deterministic).
# Both wall times go to OUT/wall_times.txt.
# Usage: bench_slurm.sh MCSLAM_EXE OUT_DIR
# Exit 77 (skipped) without the packages, unless MCSLAM_STRICT_TESTS=1 (CI), where a skip is a
# failure.
set -uo pipefail
exe="$1"
out="$2"
# shellcheck source=skip.sh
source "$(dirname "$0")/skip.sh"
fail() { echo "FAILED: $*"; exit 1; }
for tool in munged slurmctld slurmd sbatch squeue scancel python3; do
  command -v "$tool" > /dev/null 2>&1 ||
    skip "no $tool (scripts/install-deps.sh installs slurm-wlm and munge)"
done

rm -rf "$out"
mkdir -p "$out"
out="$(cd "$out" && pwd)"
# munged refuses folders that others may write to: the cluster lives in a fresh one in /tmp.
c="$(mktemp -d "${TMPDIR:-/tmp}/mcslam-slurm.XXXXXX")" || fail "mktemp"
mkdir -p "$c/munge" "$c/state" "$c/spool" "$c/log"
chmod 755 "$c" "$c/munge"  # and wants its socket's folder open to all, the key closed
user="$(id -un)"

# --- the cluster --------------------------------------------------------------------------------
pids=()
stop_cluster() {
  if [ -f "$c/slurm.conf" ]; then  # cancel what is left, and let slurmd end its steps
    scancel --full --quiet --user="$user" > /dev/null 2>&1
    for _ in $(seq 1 30); do
      [ -z "$(squeue --noheader 2> /dev/null)" ] && break
      sleep 1
    done
  fi
  for ((i = ${#pids[@]} - 1; i >= 0; i--)); do kill "${pids[$i]}" 2> /dev/null; done
  for pid in "${pids[@]}"; do
    for _ in $(seq 1 50); do kill -0 "$pid" 2> /dev/null || break; sleep 0.1; done
    kill -9 "$pid" 2> /dev/null
    wait "$pid" 2> /dev/null
  done
  cp -r "$c/log" "$out/cluster-logs" 2> /dev/null
  cp "$c/slurm.conf" "$out/cluster-logs/" 2> /dev/null
  rm -rf "$c"
}
trap stop_cluster EXIT

free_port() {
  python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])'
}
dd if=/dev/urandom of="$c/munge/munge.key" bs=1024 count=1 status=none
chmod 400 "$c/munge/munge.key"
cat > "$c/slurm.conf" << EOF
ClusterName=mcslamtest
SlurmctldHost=localhost(127.0.0.1)
SlurmctldPort=$(free_port)
SlurmdPort=$(free_port)
SlurmUser=$user
SlurmdUser=$user
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$c/munge/munge.sock
StateSaveLocation=$c/state
SlurmdSpoolDir=$c/spool
SlurmctldPidFile=$c/slurmctld.pid
SlurmdPidFile=$c/slurmd.pid
SlurmctldLogFile=$c/log/slurmctld.log
SlurmdLogFile=$c/log/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SchedulerType=sched/builtin
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
MpiDefault=none
MailProg=/bin/true
ReturnToService=2
KillWait=5
NodeName=mcslamnode NodeAddr=127.0.0.1 NodeHostname=localhost CPUs=$(nproc) State=UNKNOWN
PartitionName=debug Nodes=mcslamnode Default=YES MaxTime=INFINITE State=UP
EOF
export SLURM_CONF="$c/slurm.conf"
munged -F --socket="$c/munge/munge.sock" --key-file="$c/munge/munge.key" \
  --pid-file="$c/munge/munged.pid" --seed-file="$c/munge/seed" --log-file="$c/log/munged.log" \
  > "$c/log/munged.out" 2>&1 &
pids+=($!)
for _ in $(seq 1 50); do [ -S "$c/munge/munge.sock" ] && break; sleep 0.1; done
[ -S "$c/munge/munge.sock" ] || { cat "$c/log/munged.out"; fail "munged did not start"; }
slurmctld -D > "$c/log/slurmctld.out" 2>&1 &
pids+=($!)
slurmd -D -N mcslamnode > "$c/log/slurmd.out" 2>&1 &
pids+=($!)
for _ in $(seq 1 100); do
  sinfo --noheader --states=idle 2> /dev/null | grep -q idle && break
  sleep 0.2
done
sinfo --noheader --states=idle 2> /dev/null | grep -q idle ||
  { tail -n 20 "$c"/log/*; fail "the node did not come up"; }
echo "cluster up: $(sinfo --noheader)"

# Waits until none of the given jobs is queued or running (at most $1 seconds).
wait_jobs() {
  local limit="$1"
  shift
  local list
  list=$(IFS=,; echo "$*")
  for _ in $(seq 1 "$limit"); do
    [ -z "$(squeue --noheader --jobs="$list" 2> /dev/null)" ] && return 0
    sleep 1
  done
  squeue
  fail "jobs $list still queued or running after $limit s"
}
# The job ids in `mcslam bench --executor slurm`'s message: array, then collect.
jobs_in() { sed -n 's/.*job array \([0-9]*\) .*, and job \([0-9]*\) to collect.*/\1 \2/p' "$1"; }
now() { date +%s.%N; }

# --- data -----------------------------------------------------------------------------------
data="$out/data"
"$exe" synth --output "$data/room_a" --frames 30 --width 320 --height 240 -q || fail "synth"
"$exe" synth --output "$data/room_b" --frames 30 --width 320 --height 240 --seed 7 -q ||
  fail "synth"
mkdir -p "$out/hang"
cp -r "$data/room_a" "$out/hang/room_hang"
rm "$out/hang/room_hang/camera.yaml"
mkfifo "$out/hang/room_hang/camera.yaml"  # `mcslam run` waits for it forever, using no CPU
bench_args=(--runs 2 --modes sequential --configs points,planes --quiet)

# --- 1. a rejected submission ---------------------------------------------------------------
"$exe" bench "$data" "${bench_args[@]}" --output "$out/rejected" --executor slurm \
  --partition nope > "$out/rejected.out" 2> "$out/rejected.err"
rc=$?
[ $rc -eq 1 ] || fail "bad partition: exit $rc, expected 1"
grep -q "sbatch rejected $out/rejected/slurm/runs-1.sbatch: .*invalid partition" \
  "$out/rejected.err" || { cat "$out/rejected.err"; fail "bad partition: no clear error"; }

# --- 2. a task killed at its time limit, then resubmitted --------------------------------------
"$exe" bench "$out/hang" --runs 1 --modes sequential --configs points --quiet \
  --output "$out/timeout" --executor slurm --time-limit 1 > "$out/timeout.out" ||
  fail "submitting the hanging bench"
read -r hang_array hang_collect <<< "$(jobs_in "$out/timeout.out")"
[ -n "$hang_collect" ] || { cat "$out/timeout.out"; fail "no job ids in the message"; }

# --- 3. the same bench through Slurm and locally, while the hanging task waits for its limit
# (it takes no CPU; Slurm enforces the limit 60-90 s after the start): submitted first, the Slurm
# bench runs on the node's other core beside the local one ----------------------------------
t2=$(now)
"$exe" bench "$data" "${bench_args[@]}" --output "$out/slurm" --executor slurm --array-limit 8 \
  > "$out/slurm.out" || fail "submitting the bench"
cat "$out/slurm.out"
read -r array collect <<< "$(jobs_in "$out/slurm.out")"
t0=$(now)
"$exe" bench "$data" "${bench_args[@]}" --output "$out/local" > "$out/local.err" 2>&1 ||
  { cat "$out/local.err"; fail "local bench"; }
t1=$(now)
wait_jobs 480 "$array" "$collect"
t3=$(now)
wait_jobs 300 "$hang_array" "$hang_collect"
grep -q "no result: Slurm ended the task at its time limit; Slurm: TIMEOUT (job ${hang_array}_0" \
  "$out/timeout/results.md" || { cat "$out/timeout/results.md"; fail "no TIMEOUT in the tables"; }
grep -q "log: slurm/task-${hang_array}_0.out" "$out/timeout/results.md" || fail "no log path"
rm "$out/hang/room_hang/camera.yaml" && cp "$data/room_a/camera.yaml" "$out/hang/room_hang/"
"$exe" bench --resubmit-failed "$out/timeout" > "$out/resubmit.out" || fail "resubmitting"
grep -q "submitted 1 of 1 runs" "$out/resubmit.out" || { cat "$out/resubmit.out"; fail "resubmit"; }
read -r re_array re_collect <<< "$(jobs_in "$out/resubmit.out")"
wait_jobs 240 "$re_array" "$re_collect"

[ -f "$out/slurm/results.md" ] || { cat "$out"/slurm/slurm/*.out; fail "the collect job wrote no tables"; }
grep -q "## Failed runs"$'\n\n'"None." "$out/slurm/results.md" ||
  { cat "$out/slurm/results.md"; fail "runs failed under Slurm"; }
grep -q "Slurm job array $array" "$out/slurm/results.md" || fail "the tables do not say Slurm"
grep -q "## Failed runs"$'\n\n'"None." "$out/timeout/results.md" ||
  { cat "$out/timeout/results.md"; fail "the resubmitted run did not succeed"; }
python3 - "$out/local" "$out/slurm" << 'EOF' || fail "the tables differ"
import json, sys
local, slurm = (json.load(open(d + "/results.json")) for d in sys.argv[1:3])
def figures(results):
    return [(s["name"], r["config"], [(u["mode"], u["index"], u["ok"], u["frames"],
             u["ate_rmse_m"], u["rpe_trans_m"], u["rpe_rot_deg"], u["tracked_ratio"])
             for u in r["runs"]]) for s in results["sequences"] for r in s["results"]]
a, b = figures(local), figures(slurm)
assert len(a) == 4 and all(len(runs) == 2 for _, _, runs in a), a
assert all(u[2] and u[4] is not None for _, _, runs in a for u in runs), "a local run failed"
if a != b:
    sys.exit("local %s\nslurm %s" % (a, b))
def accuracy(path):  # the main tables' cells from configuration to tracked (not the speed)
    rows, inside = [], False
    for line in open(path + "/results.md"):
        if line.startswith("| configuration | ATE RMSE (m) |"):
            inside = True
        elif inside and line.startswith("| ") :
            rows.append(line.split("|")[1:7])
        elif inside and not line.startswith("|---"):
            inside = False
    return rows
ra, rb = accuracy(sys.argv[1]), accuracy(sys.argv[2])
if len(ra) != 4 or ra != rb:
    sys.exit("tables:\n%s\n%s" % (ra, rb))
print("same figures: %d configurations, %d runs" % (len(a), sum(len(r) for _, _, r in a)))
EOF
python3 -c "print('local bench: %.1f s\nslurm bench (submission to collected tables, beside the local one): %.1f s'
               % ($t1 - $t0, $t3 - $t2))" | tee "$out/wall_times.txt"
echo "passed"
