#!/usr/bin/env bash
# The GPU measurement, ready for a machine with a GPU and no package registry: the adapter and
# driver, then `quatcurve bench --json` for the workloads docs/PERFORMANCE.md tracks, each on
# the GPU and on the CPU path of the same machine, as JSON files and one Markdown table under
# one output directory. It stops cleanly at its time limit: a workload that would start after
# it is listed as not run, one cut short as timed out.
#
#   scripts/device-check.sh [--plan] [--bin QUATCURVE] [--out DIR] [--limit SECONDS] [--fitted F.qcf ...]
#                           [--playback FILE]
#
# The binary is built beforehand on a plain x86-64 machine and carried along:
#   RUSTFLAGS="-C target-cpu=x86-64-v2" cargo build --release   # target/release/quatcurve
# --plan prints what would run, without running it (no GPU needed).
set -euo pipefail

bin=target/release/quatcurve out=device-check limit=480 plan=0 fitted=() playback=""
while (($#)); do
    case $1 in
        --plan) plan=1 ;;
        --bin) bin=$2; shift ;;
        --out) out=$2; shift ;;
        --limit) limit=$2; shift ;;
        --playback) playback=$2; shift ;;
        --fitted) shift; while (($#)) && [[ $1 != --* ]]; do fitted+=("$1"); shift; done; continue ;;
        *) echo "device-check: unknown argument $1 (see the head of $0)" >&2; exit 2 ;;
    esac
    shift
done

# name | bench arguments. Each runs on the GPU and the CPU path (the reference is the oracle,
# not a contender). The large batches take 3 timed runs, the rest 5.
workloads=(
    "uniform cubic B-spline 10k x 1000|--tracks 10000 --samples 1000 --curve bspline --knots uniform"
    "uniform cubic B-spline 10k x 1000, derivatives|--tracks 10000 --samples 1000 --curve bspline --knots uniform --derivatives"
    "bspline-interp 10k x 1000|--tracks 10000 --samples 1000 --curve bspline-interp"
    "slerp 10k x 1000|--tracks 10000 --samples 1000 --curve slerp"
    "squad 10k x 1000|--tracks 10000 --samples 1000 --curve squad"
    "bezier 10k x 1000|--tracks 10000 --samples 1000 --curve bezier"
    "hermite 10k x 1000|--tracks 10000 --samples 1000 --curve hermite"
    "hermite 10k x 1000, derivatives|--tracks 10000 --samples 1000 --curve hermite --derivatives"
    "nam-kim 10k x 1000|--tracks 10000 --samples 1000 --curve nam-kim"
    "uniform cubic B-spline 100k x 1000|--tracks 100000 --samples 1000 --curve bspline --knots uniform --runs 3"
    "uniform cubic B-spline 1M x 100|--tracks 1000000 --samples 100 --curve bspline --knots uniform --runs 3"
    "uniform cubic B-spline 1M x 10|--tracks 1000000 --samples 10 --curve bspline --knots uniform --runs 3"
)
if ((${#fitted[@]})); then
    workloads+=("fitted decode, batched, 100 copies|--fitted ${fitted[*]} --copies 100")
fi

if [[ -n $playback ]]; then
    workloads+=("crowd playback, 10k and 100k instances blending two clips|--playback $playback --instances 10000,100000 --runs 3")
fi

if ((plan)); then
    echo "device-check plan: $bin, at most $limit s, into $out/"
    echo "  adapter and driver: nvidia-smi (when present); $bin bench --devices gpu --tracks 1 --samples 1 --runs 1 --json"
    i=0
    for w in "${workloads[@]}"; do
        i=$((i + 1))
        echo "  $i. ${w%%|*}: $bin bench ${w#*|} --devices gpu,cpu --json > $out/$i.json"
    done
    ((${#fitted[@]})) || echo "  (fitted decode: pass --fitted with containers from \`quatcurve fit\`)"
    [[ -n $playback ]] || echo "  (crowd playback: pass --playback with a file of clips: Fox.glb, 24 skin joints; cmu_131_01.bvh, 31 joints)"
    echo "  then $out/summary.md: one row per workload and device"
    exit 0
fi

[[ -x $bin ]] || { echo "device-check: no binary at $bin (build it first, see the head of $0)" >&2; exit 2; }
mkdir -p "$out"
start=$SECONDS
left() { echo $((limit - (SECONDS - start))); }
# Mesa's Vulkan drivers ask for a runtime directory; a bare machine may have none.
export XDG_RUNTIME_DIR=${XDG_RUNTIME_DIR:-$(mktemp -d)}

{
    echo "# device check, $(date -u '+%Y-%m-%d %H:%M UTC')"
    echo
    echo "- host: $(uname -srm), $(nproc) CPU threads, $(awk '/MemTotal/ {printf "%.0f GiB", $2 / 1048576}' /proc/meminfo)"
    if command -v nvidia-smi >/dev/null; then
        echo "- GPU (nvidia-smi): $(nvidia-smi --query-gpu=name,driver_version,memory.total,clocks.max.memory --format=csv,noheader 2>&1 | head -1)"
    fi
} >"$out/summary.md"
"$bin" bench --devices gpu --tracks 1 --samples 1 --runs 1 --json >"$out/adapter.json" 2>"$out/adapter.err" || true
adapter=$(sed -n 's/.*"adapter":"\([^"]*\)".*/\1/p' "$out/adapter.json")
driver=$(sed -n 's/.*"driver":"\([^"]*\)".*/\1/p' "$out/adapter.json")
echo "- adapter: ${adapter:-none ($(head -c 300 "$out/adapter.err"))}; driver: ${driver:-unknown}" >>"$out/summary.md"
cat "$out/summary.md"

{
    echo
    echo "| # | workload | device | M samples/s end to end | prepared (dispatches alone) | roofline | prepared / roofline | end to end / prepared |"
    echo "|---|---|---|---|---|---|---|---|"
} >>"$out/summary.md"

# One Markdown row per device of a bench JSON report (a fitted report: ns per bone-pose).
rows() {
    awk -v n="$1" -v name="$2" '
        # A field of one flat JSON object: a string (commas and all) or a number.
        function field(s, key,    m) {
            if (match(s, "\"" key "\":\"[^\"]*\"")) return substr(s, RSTART + length(key) + 4, RLENGTH - length(key) - 5)
            if (match(s, "\"" key "\":[^,}]*")) return substr(s, RSTART + length(key) + 3, RLENGTH - length(key) - 3)
            return ""
        }
        function mega(v) { return v == "" ? "-" : sprintf("%.2f", v / 1e6) }
        {
            sub(/.*"results":\[/, ""); n_rows = split($0, parts, /\},\{/)
            for (i = 1; i <= n_rows; i++) {
                r = parts[i]; device = field(r, "device")
                if (field(r, "instance_joints_per_s") != "") {
                    printf "| %s | %s | %s | %s instances: %.2f M instance-joints/s, %.2f ms a frame | - | - | - | - |\n", n, name, device, field(r, "instances"), field(r, "instance_joints_per_s") / 1e6, field(r, "ms_per_frame")
                    continue
                }
                if (field(r, "ns_per_bone_pose") != "") {
                    printf "| %s | %s | %s | %.1f ns per bone-pose | - | - | - | - |\n", n, name, device, field(r, "ns_per_bone_pose")
                    continue
                }
                e = field(r, "samples_per_s"); d = field(r, "prepared_samples_per_s"); f = field(r, "roofline_samples_per_s")
                printf "| %s | %s | %s | %s | %s | %s | %s | %s |\n", n, name, device, mega(e), mega(d), mega(f),
                    (d != "" && f != "") ? sprintf("%.2f", d / f) : "-", (d != "") ? sprintf("%.2f", e / d) : "-"
            }
        }' "$3"
}

i=0
for w in "${workloads[@]}"; do
    i=$((i + 1))
    name=${w%%|*} args=${w#*|}
    if (($(left) < 20)); then
        echo "| $i | $name | - | not run: the time limit | | | | |" >>"$out/summary.md"
        continue
    fi
    echo "$i. $name ($(left) s left)" >&2
    # shellcheck disable=SC2086 # the arguments are words
    if timeout "$(left)" "$bin" bench $args --devices gpu,cpu --json >"$out/$i.json" 2>"$out/$i.err"; then
        rows "$i" "$name" "$out/$i.json" >>"$out/summary.md"
    else
        status=$?
        why=$([[ $status == 124 ]] && echo "timed out at the time limit" || echo "failed ($status): $(tail -c 200 "$out/$i.err" | tr '\n|' '  ')")
        echo "| $i | $name | - | $why | | | | |" >>"$out/summary.md"
    fi
done
echo >>"$out/summary.md"
echo "$((SECONDS - start)) s in all; JSON per workload in $out/" >>"$out/summary.md"
cat "$out/summary.md"
