#!/usr/bin/env bash
# A real Slurm run on one machine: installs Slurm + munge (Debian packages) if missing,
# starts a one-node cluster on localhost, runs the smoke DAG through
# snakemake-executor-plugin-slurm and checks that its outputs equal a local run's
# (compare_runs.py). Needs root (apt-get, the daemons). Exits non-zero on any failure.
#
#   workflow/profiles/slurm/test-local.sh [LOCAL_RUN_DIR]
#
# LOCAL_RUN_DIR: an existing local smoke run (a --directory holding results/) to compare
# with; without it the script runs the smoke DAG locally first.
# Environment: PYTHON (the venv's python; default: python3 on PATH), WORK (scratch
# directory; default: a new /tmp/finray-slurm.*), NICE (default 19), RTOL (compare_runs.py
# tolerance, default 1e-9).
set -euo pipefail

REPO=$(cd "$(dirname "${BASH_SOURCE[0]}")/../../.." && pwd)
PYTHON=${PYTHON:-$(command -v python3)}
WORK=${WORK:-$(mktemp -d /tmp/finray-slurm.XXXXXX)}
NICE=${NICE:-19}
LOCAL_RUN=${1:-}
T0=$(date +%s)

log() { printf '[test-local %s +%4ss] %s\n' "$(date -u +%H:%M:%S)" "$(( $(date +%s) - T0 ))" "$*"; }
die() { log "FAILED: $*" >&2; exit 1; }

[[ $(id -u) -eq 0 ]] || die "needs root (apt-get, munged, slurmctld, slurmd)"
"$PYTHON" -c "import snakemake_executor_plugin_slurm" 2>/dev/null \
    || die "$PYTHON lacks snakemake-executor-plugin-slurm (pip install -e . installs the pinned one)"
export PYTHONPATH="$REPO/src${PYTHONPATH:+:$PYTHONPATH}"   # this checkout's finray
mkdir -p "$WORK/slurm/state" "$WORK/slurm/spool" "$WORK/slurm/log"
log "repo $REPO, python $PYTHON, work $WORK"

# ------------------------------------------------------------------ install
if ! command -v slurmctld >/dev/null || ! command -v slurmd >/dev/null || ! command -v munged >/dev/null; then
    log "installing slurm-wlm and munge (apt-get)"
    export DEBIAN_FRONTEND=noninteractive
    apt-get update -qq || die "apt-get update"
    apt-get install -y -q --no-install-recommends slurm-wlm munge >"$WORK/slurm/log/apt.log" 2>&1 \
        || die "apt-get install slurm-wlm munge (see $WORK/slurm/log/apt.log)"
fi
log "slurm $(slurmctld -V | awk '{print $2}'), $(munged -V 2>&1 | head -1)"

# ------------------------------------------------------------------ daemons
PIDS=()
cleanup() {
    local rc=$?
    log "stopping the daemons this script started"
    for pidfile in "${PIDS[@]}"; do
        [[ -s $pidfile ]] && kill "$(cat "$pidfile")" 2>/dev/null || true
    done
    if [[ -L /etc/slurm/slurm.conf ]]; then
        rm -f /etc/slurm/slurm.conf
        [[ -e $WORK/slurm/slurm.conf.orig ]] && mv "$WORK/slurm/slurm.conf.orig" /etc/slurm/slurm.conf
    fi
    exit "$rc"
}
trap cleanup EXIT

if ! munge -n 2>/dev/null | unmunge >/dev/null 2>&1; then
    [[ -s /etc/munge/munge.key ]] || { mungekey --create --keyfile /etc/munge/munge.key \
        || dd if=/dev/urandom of=/etc/munge/munge.key bs=1024 count=1 status=none; }
    chown munge:munge /etc/munge/munge.key && chmod 400 /etc/munge/munge.key
    mkdir -p /run/munge /var/log/munge /var/lib/munge
    chown munge:munge /run/munge /var/log/munge /var/lib/munge
    runuser -u munge -- munged || die "munged did not start"
    PIDS+=(/run/munge/munged.pid)
    sleep 1
    munge -n | unmunge >/dev/null || die "munge credential round trip"
    log "munged started"
else
    log "munged already running"
fi

NODE=$(hostname -s)
HW=$(slurmd -C | head -1)   # what slurmd will find: CPUs, RealMemory
CPUS=$(grep -o 'CPUs=[0-9]*' <<<"$HW" | cut -d= -f2)
MEM=$(grep -o 'RealMemory=[0-9]*' <<<"$HW" | cut -d= -f2)
[[ -n $CPUS && -n $MEM ]] || die "slurmd -C gave no CPUs/RealMemory: $HW"
export SLURM_CONF="$WORK/slurm/slurm.conf"
cat >"$SLURM_CONF" <<CONF
# one-node cluster on localhost for test-local.sh (container-safe: no cgroups)
ClusterName=finraylocal
SlurmctldHost=$NODE(127.0.0.1)
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
StateSaveLocation=$WORK/slurm/state
SlurmdSpoolDir=$WORK/slurm/spool
SlurmctldPidFile=$WORK/slurm/slurmctld.pid
SlurmdPidFile=$WORK/slurm/slurmd.pid
SlurmctldLogFile=$WORK/slurm/log/slurmctld.log
SlurmdLogFile=$WORK/slurm/log/slurmd.log
SlurmctldPort=6817
SlurmdPort=6818
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/none
MpiDefault=none
SwitchType=switch/none
SchedulerType=sched/backfill
SelectType=select/cons_tres
SelectTypeParameters=CR_Core_Memory
ReturnToService=2
MinJobAge=600
NodeName=$NODE NodeAddr=127.0.0.1 CPUs=$CPUS RealMemory=$MEM State=UNKNOWN
PartitionName=finray Nodes=$NODE Default=YES MaxTime=INFINITE State=UP
CONF
# srun inside a batch job reads the default path, not the SLURM_CONF of sbatch's caller:
# link it there, keeping (and putting back) a slurm.conf that is not ours
ETC_CONF=/etc/slurm/slurm.conf
if [[ -e $ETC_CONF && ! -L $ETC_CONF ]] && ! grep -q '^# one-node cluster on localhost for test-local.sh' "$ETC_CONF"; then
    mv "$ETC_CONF" "$WORK/slurm/slurm.conf.orig"
    log "moved the existing $ETC_CONF to $WORK/slurm/slurm.conf.orig (put back on exit)"
fi
mkdir -p /etc/slurm && ln -sfn "$SLURM_CONF" "$ETC_CONF"
log "slurm.conf: node $NODE, CPUs=$CPUS, RealMemory=$MEM MB, partition finray ($ETC_CONF -> $SLURM_CONF)"

slurmctld -c -f "$SLURM_CONF" || die "slurmctld (see $WORK/slurm/log/slurmctld.log)"
PIDS+=("$WORK/slurm/slurmctld.pid")
nice -n "$NICE" slurmd -f "$SLURM_CONF" -N "$NODE" || die "slurmd (see $WORK/slurm/log/slurmd.log)"
PIDS+=("$WORK/slurm/slurmd.pid")   # jobs inherit slurmd's nice value
for _ in $(seq 60); do
    sinfo -h -o '%T' 2>/dev/null | grep -qx idle && break
    sleep 1
done
sinfo -h -o '%T' | grep -qx idle || { sinfo; die "node not idle after 60 s (see $WORK/slurm/log/)"; }
log "sinfo: $(sinfo -h -o '%P %D %T %c cpus %m MB')"
[[ $(timeout 60 srun -N1 -n1 hostname) == "$(hostname)" ]] || die "srun hostname"
log "srun hostname: ok"

# ------------------------------------------------------------------ runs
smk() { nice -n "$NICE" "$PYTHON" -m snakemake -s "$REPO/Snakefile" \
            --configfile "$REPO/config/smoke.yaml" "$@"; }

if [[ -z $LOCAL_RUN ]]; then
    LOCAL_RUN="$WORK/run-local"
    log "local smoke run -> $LOCAL_RUN"
    t=$(date +%s)
    smk --cores 2 --directory "$LOCAL_RUN" >"$WORK/local.log" 2>&1 \
        || { tail -30 "$WORK/local.log"; die "local smoke run (see $WORK/local.log)"; }
    log "local smoke run done in $(( $(date +%s) - t )) s"
else
    [[ -d $LOCAL_RUN/results ]] || die "$LOCAL_RUN holds no results/"
    log "comparing with the existing local run $LOCAL_RUN"
fi

log "Slurm smoke run -> $WORK/run-slurm"
rm -rf "$WORK/run-slurm"   # always a whole run
t=$(date +%s)
smk --workflow-profile "$REPO/workflow/profiles/slurm/local" --directory "$WORK/run-slurm" \
    >"$WORK/slurm.log" 2>&1 || { tail -40 "$WORK/slurm.log"; die "Slurm smoke run (see $WORK/slurm.log)"; }
NJOBS=$(grep -c 'Submitted batch job\|has been submitted with SLURM jobid' "$WORK/slurm.log" || true)
log "Slurm smoke run done in $(( $(date +%s) - t )) s ($NJOBS Slurm jobs submitted)"

# ------------------------------------------------------------------ compare
log "comparing $LOCAL_RUN with $WORK/run-slurm"
"$PYTHON" "$REPO/workflow/profiles/slurm/compare_runs.py" --rtol "${RTOL:-1e-9}" "$LOCAL_RUN" "$WORK/run-slurm" \
    | tee "$WORK/compare.log" || die "outputs differ (see $WORK/compare.log)"
log "PASSED: the Slurm run's outputs equal the local run's"
