#!/bin/sh
# The Slurm round trip of `vesica study` against a real Slurm on this machine
# (make test-slurm): installs Debian's slurm-wlm and munge
# if missing, starts a private munged and a single-node slurmctld + slurmd
# with a generated configuration in a temporary folder, runs a 4-cell study
# on the tiny problem of tests/test_study.c locally, submits the same study
# with the script `vesica study --emit slurm` writes, waits for the array,
# runs --collect and checks that both tables agree in every column but the
# timing and memory ones; the study carries a command-line --set, a throttle
# and a [slurm] setup line (seen run in the tasks' logs), and a second
# --emit slurm on the finished study writes no script. Stops every daemon it started and removes the
# folder on exit; exit 1 with a message on any failure.
#
#   sh tests/slurm_roundtrip.sh [build/vesica]     (as root)
#
# Environment: VESICA (the program, default build/vesica; the argument wins),
# SLURM_RT_TIMEOUT (seconds to wait for the array, default 300),
# SLURM_RT_PORT (slurmctld's port, slurmd's is the next; default 6817),
# SLURM_RT_KEEP=1 (keep the temporary folder for inspection).
set -u
V=${1:-${VESICA:-build/vesica}}
TIMEOUT=${SLURM_RT_TIMEOUT:-300}
PORT=${SLURM_RT_PORT:-6817}
PKGS="slurm-wlm munge"
T=
MUNGED= CTLD= SLURMD= JOB=

say() { echo "slurm_roundtrip: $*"; }

# The last lines of every log there is, then exit 1.
fail() {
  say "FAIL: $*" >&2
  if [ -n "$T" ]; then
    for f in "$T"/munged.out "$T"/slurmctld.out "$T"/slurmd.out "$T"/slurm/slurm/*.out; do
      [ -s "$f" ] && { echo "--- tail of $f" >&2; tail -n 15 "$f" >&2; }
    done
  fi
  exit 1
}

# Stop what this script started (by process id), then remove the folder. A
# job still queued or running is cancelled first and given 15 s to end, so
# slurmd is still there to kill its tasks.
cleanup() {
  rc=$?
  trap - EXIT INT TERM
  if [ -n "$JOB" ] && [ -n "$CTLD" ] && kill -0 "$CTLD" 2>/dev/null; then
    if [ -n "$(squeue -h -j "$JOB" 2>/dev/null)" ]; then
      say "cancelling job $JOB"
      scancel "$JOB" 2>/dev/null
      i=0
      while [ -n "$(squeue -h -j "$JOB" 2>/dev/null)" ] && [ $i -lt 30 ]; do
        sleep 0.5; i=$((i + 1))
      done
    fi
  fi
  for p in $SLURMD $CTLD $MUNGED; do
    kill "$p" 2>/dev/null || continue
    i=0
    while kill -0 "$p" 2>/dev/null && [ $i -lt 20 ]; do sleep 0.5; i=$((i + 1)); done
    kill -0 "$p" 2>/dev/null && { say "process $p ignored SIGTERM: SIGKILL"; kill -9 "$p" 2>/dev/null; }
  done
  [ -n "$MUNGED" ] && say "stopped the daemons it started (pids $MUNGED $CTLD $SLURMD)"
  if [ -n "$T" ]; then
    if [ "${SLURM_RT_KEEP:-0}" = 1 ]; then say "kept $T"; else rm -rf "$T"; fi
  fi
  exit $rc
}
trap cleanup EXIT
trap 'exit 130' INT
trap 'exit 143' TERM

# ---- prerequisites -------------------------------------------------------
[ "$(id -u)" = 0 ] || fail "must run as root (it installs packages and starts slurmd, which runs jobs as root)"
[ -x "$V" ] || fail "$V: no such program (make BUILD=... first, or VESICA=path)"
V=$(cd "$(dirname "$V")" && pwd)/$(basename "$V")
st=$(dpkg-query -W -f='${Package} ${Status}\n' $PKGS 2>/dev/null)
missing=
for p in $PKGS; do
  printf '%s\n' "$st" | grep -q "^$p install ok installed$" || missing="$missing $p"
done
if [ -n "$missing" ]; then
  say "installing$missing"
  apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends $missing ||
    fail "apt-get install$missing failed"
fi
for c in munged mungekey slurmctld slurmd sbatch squeue scontrol sinfo scancel; do
  command -v $c >/dev/null 2>&1 || fail "$c: not found after installing$PKGS"
done

# ---- munge: a private key and socket (no system munged needed or touched) --
# munged wants every folder above its socket searchable by all: 0755.
T=$(mktemp -d /tmp/vesica_slurm.XXXXXX) || fail "mktemp failed"
chmod 755 "$T"
mkdir -p "$T/state" "$T/spool"
mungekey -c -k "$T/munge.key" || fail "mungekey could not create $T/munge.key"
munged -F --key-file="$T/munge.key" --socket="$T/munge.socket" --pid-file="$T/munged.pid" \
  --log-file="$T/munged.log" --seed-file="$T/munged.seed" >"$T/munged.out" 2>&1 &
MUNGED=$!
i=0
until [ -S "$T/munge.socket" ]; do
  kill -0 "$MUNGED" 2>/dev/null || fail "munged exited"
  [ $i -ge 20 ] && fail "munged: no socket after 10 s"
  sleep 0.5; i=$((i + 1))
done
munge -S "$T/munge.socket" -n | unmunge -S "$T/munge.socket" >/dev/null ||
  fail "munge/unmunge through $T/munge.socket failed"
say "munged running (pid $MUNGED)"

# ---- Slurm: one node (this machine), one partition -------------------------
# No cgroup plugin (proctrack/linuxproc, task/none): a container need not
# give slurmd a writable cgroup tree. No accounting database: the finished
# tasks' states come from scontrol and the job-completion file.
H=$(hostname -s)
NODE=$(slurmd -C | grep '^NodeName=') || fail "slurmd -C could not describe this machine"
cat >"$T/slurm.conf" <<EOF
ClusterName=vesicatest
SlurmctldHost=$H
SlurmctldPort=$PORT
SlurmdPort=$((PORT + 1))
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
AuthInfo=socket=$T/munge.socket
CredType=cred/munge
StateSaveLocation=$T/state
SlurmdSpoolDir=$T/spool
SlurmctldPidFile=$T/slurmctld.pid
SlurmdPidFile=$T/slurmd.pid
MailProg=/bin/true
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/filetxt
JobCompLoc=$T/jobcomp.txt
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
MpiDefault=none
ReturnToService=2
MinJobAge=600
$NODE State=UNKNOWN
PartitionName=debug Nodes=$H Default=YES MaxTime=INFINITE State=UP
EOF
export SLURM_CONF="$T/slurm.conf"
slurmctld -D -i -f "$SLURM_CONF" >"$T/slurmctld.out" 2>&1 &
CTLD=$!
slurmd -D -f "$SLURM_CONF" >"$T/slurmd.out" 2>&1 &
SLURMD=$!
i=0
until [ "$(sinfo -h -n "$H" -o %T 2>/dev/null)" = idle ]; do
  kill -0 "$CTLD" 2>/dev/null || fail "slurmctld exited"
  kill -0 "$SLURMD" 2>/dev/null || fail "slurmd exited"
  [ $i -ge 60 ] && fail "node $H not idle after 30 s: $(sinfo -h -n "$H" -o %T 2>&1)"
  sleep 0.5; i=$((i + 1))
done
say "slurmctld (pid $CTLD) and slurmd (pid $SLURMD) up: $(sinfo -h -o '%P %a %D %T %N %c CPUs %m MB')"

# ---- the study: tests/test_study.c's tiny problem, 4 one-step cells --------
# newton converges at dt* 5e-3, explicit Euler fails at dt* 1: both outcomes
# go through the round trip.
printf '[shape]\ntype = sphere\n' >"$T/base.ini"
cat >"$T/study.ini" <<EOF
[study]
problem = base.ini
run = step
time_limit = 120
[set]
geometry.epsilon = 0.2
geometry.box_r = 2
geometry.box_z = 2
geometry.band = 2
geometry.h_band = 0.7
geometry.h_far = 0.3
shape.mode = 2
shape.delta = 0.15
[slurm]
mem = 1G
throttle = 2
setup = "echo 'slurm setup ran'; export VESICA_RT=1"
[axes]
solver.backend = newton, euler
time.dt_initial = 5e-3, 1
EOF
NCELLS=4

t0=$(date +%s)
SET="--set solver.max_iter=100"
"$V" study "$T/study.ini" $SET --out "$T/local" --jobs 2 --quiet || fail "the local study failed"
say "local study: $(($(date +%s) - t0)) s"

"$V" study "$T/study.ini" $SET --out "$T/slurm" --emit slurm || fail "--emit slurm failed"
grep -E '^#SBATCH|^exec|^echo' "$T/slurm/study.sbatch" | sed 's/^/  /'
grep -q '^#SBATCH --array=0-3%2$' "$T/slurm/study.sbatch" || fail "no --array=0-3%2 in the script"
grep -q -- "--set 'solver.max_iter=100' --max-cells" "$T/slurm/study.sbatch" || fail "the script does not pass --set"
cd "$T" || fail "cd $T"
t0=$(date +%s)
sub=$(sbatch "$T/slurm/study.sbatch" 2>&1) || fail "sbatch: $sub"
echo "$sub"
JOB=$(printf '%s\n' "$sub" | sed -n 's/^Submitted batch job \([0-9][0-9]*\).*/\1/p')
[ -n "$JOB" ] || fail "no job id in sbatch's answer: $sub"

# Wait for the array to leave the queue, printing the queue when it changes.
last=
while :; do
  q=$(squeue -h -j "$JOB" -o '%i %T %R' 2>&1) || fail "squeue: $q"
  [ -z "$q" ] && break
  if [ "$q" != "$last" ]; then
    echo "squeue after $(($(date +%s) - t0)) s:"; printf '%s\n' "$q" | sed 's/^/  /'; last=$q
  fi
  [ $(($(date +%s) - t0)) -ge "$TIMEOUT" ] && fail "array job $JOB not done after $TIMEOUT s"
  kill -0 "$SLURMD" 2>/dev/null || fail "slurmd exited while the array ran"
  sleep 1
done
say "array job $JOB left the queue after $(($(date +%s) - t0)) s"

# Every task ended COMPLETED with exit code 0 (a failed cell is still a
# task that ran: --cell exits 0 once the cell's outcome is recorded).
states=$(scontrol -o show job "$JOB" 2>&1) || fail "scontrol show job $JOB: $states"
printf '%s\n' "$states" | tr ' ' '\n' | grep -E '^(JobId|ArrayTaskId|JobState|ExitCode|RunTime)=' |
  paste -d ' ' - - - - - | sort -t= -k3n | sed 's/^/  /'
n=$(printf '%s\n' "$states" | grep -c 'JobState=COMPLETED .*ExitCode=0:0')
[ "$n" -eq $NCELLS ] || fail "$n of $NCELLS array tasks COMPLETED with exit code 0"
echo "job completion log ($T/jobcomp.txt):"
tr ' ' '\n' <"$T/jobcomp.txt" | grep -E '^(JobId|JobState|NodeList|ArrayTaskId|ExitCode)=' |
  paste -d ' ' - - - - - | sed 's/^/  /'

n=$(cat "$T"/slurm/slurm/*.out | grep -c '^slurm setup ran$')
[ "$n" -eq $NCELLS ] || fail "the [slurm] setup line ran in $n of $NCELLS tasks' logs"
"$V" study "$T/study.ini" $SET --out "$T/slurm" --collect --quiet || fail "--collect failed"
again=$("$V" study "$T/study.ini" $SET --out "$T/slurm" --emit slurm) || fail "a second --emit failed"
[ -e "$T/slurm/study.sbatch" ] && fail "--emit slurm on a finished study left a script: $again"
say "a second --emit: $again"

# ---- the tables: equal but for the timing and memory columns -------------
# RFC 4180 fields (quoted, quotes doubled) split by hand: mawk has no FPAT.
stable() {
  awk '
  function split_csv(line, f,   n, i, c, q, s) {
    n = 1; s = ""; q = 0
    for (i = 1; i <= length(line); i++) {
      c = substr(line, i, 1)
      if (q) {
        if (c == "\"") { if (substr(line, i + 1, 1) == "\"") { s = s c; i++ } else q = 0 }
        else s = s c
      } else if (c == "\"") q = 1
      else if (c == ",") { f[n++] = s; s = "" }
      else s = s c
    }
    f[n] = s
    return n
  }
  BEGIN { drop["setup_seconds"] = drop["loop_seconds"] = drop["seconds_per_step"] = 1
          drop["wall_seconds"] = drop["cpu_seconds"] = drop["peak_mb"] = 1 }
  { n = split_csv($0, f); out = ""
    for (i = 1; i <= n; i++) {
      if (NR == 1) keep[i] = !(f[i] in drop)
      if (keep[i]) out = out (out == "" ? "" : "|") f[i]
    }
    print out }' "$1"
}
[ -s "$T/local/study.csv" ] || fail "$T/local/study.csv: missing"
[ -s "$T/slurm/study.csv" ] || fail "$T/slurm/study.csv: missing"
stable "$T/local/study.csv" >"$T/local.tab"
stable "$T/slurm/study.csv" >"$T/slurm.tab"
echo "local table (columns but timing and memory, | separated):"
sed 's/^/  /' "$T/local.tab"
rows=$(($(wc -l <"$T/local.tab") - 1))
[ "$rows" -eq $NCELLS ] || fail "the local table has $rows rows, not $NCELLS"
grep -q '|converged|' "$T/local.tab" || fail "no converged cell in the local table"
if ! diff "$T/local.tab" "$T/slurm.tab" >"$T/tab.diff"; then
  echo "local (<) against Slurm (>):"; cat "$T/tab.diff"
  fail "the collected table differs from the local run's"
fi
say "PASS: the Slurm-collected table equals the local one ($NCELLS cells)"
