#!/usr/bin/env bash
# The layers' one-way dependencies (docs/ARCHITECTURE.md), checked and drawn.
#
#   scripts/layers.sh            checks the sources: every #include "evar/<layer>/..." in a
#                                layer and every evar_<layer> its CMakeLists.txt links must be
#                                one the layer may use (the table below); exit 1 naming each
#                                file and line that breaks it
#   scripts/layers.sh BUILD_DIR  also asks CMake for the build's target graph
#                                (cmake --graphviz on BUILD_DIR) and prints the links between
#                                the layers' libraries, as ARCHITECTURE.md shows them
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)

# What each layer may use, downstream first: acquisition -> geometry -> deform -> overlay ->
# node, session (recorded sessions) and sim (which makes them) feeding in from the side,
# app on top; base (an owned file descriptor, elapsed time) under all of them.
declare -A may_use=(
  [base]="base"
  [acquisition]="acquisition base"
  [geometry]="geometry base"
  [deform]="deform geometry base"
  [prepare]="prepare geometry base"
  [overlay]="overlay geometry base"
  [session]="session geometry acquisition base"
  [sim]="sim session geometry acquisition base"
  [node]="node acquisition geometry deform overlay base"
  [app]="app node session sim acquisition geometry deform prepare overlay base"
)
# The CMake library of each layer.
declare -A target=([base]=evar_base [acquisition]=evar_acquisition [geometry]=evar_geometry [deform]=evar_deform [prepare]=evar_prepare
  [overlay]=evar_overlay [session]=evar_session [sim]=evar_sim [node]=evar_node [app]=evar_cli)
declare -A layer_of
for l in "${!target[@]}"; do layer_of[${target[$l]}]=$l; done

bad=0
for layer in "${!may_use[@]}"; do
  allowed=" ${may_use[$layer]} "
  while IFS=: read -r file line used; do
    if [[ $allowed != *" $used "* ]]; then
      echo "$file:$line: $layer includes evar/$used/ (a $layer file may include: ${may_use[$layer]})"
      bad=1
    fi
  done < <(cd "$root" && grep -rnoE '#include "evar/[a-z_]+/' "$layer" --include='*.hpp' --include='*.cpp' |
             sed -E 's|#include "evar/([a-z_]+)/$|\1|')
  # evar_<x> named in the layer's target_link_libraries calls (helper targets such as
  # evar_opencv are not layers and are not checked).
  while IFS=: read -r line used; do
    l=${layer_of[$used]:-}
    if [[ -n $l && $allowed != *" $l "* ]]; then
      echo "$layer/CMakeLists.txt:$line: ${target[$layer]} links $used (layer $l; $layer may use: ${may_use[$layer]})"
      bad=1
    fi
  done < <(awk '/target_link_libraries\(/{on=1} on{print NR": "$0} /\)/{on=0}' "$root/$layer/CMakeLists.txt" |
             grep -oE '^[0-9]+:|evar_[a-z_]+' | awk '/:$/{n=$0; next} {print n $0}' | sed 's/: */:/' |
             grep -v ":${target[$layer]}$" || true)
done
# deform works on meshes and curves: no image library reaches it (geometry keeps OpenCV
# private; the layers that handle images link it themselves).
while IFS= read -r hit; do
  echo "$hit: deform includes OpenCV (it works on meshes and curves; images stay in geometry, overlay and above)"
  bad=1
done < <(cd "$root" && grep -rnE '#include <opencv2/' deform --include='*.hpp' --include='*.cpp' || true)
if [[ $bad != 0 ]]; then
  echo "layers.sh: a dependency against the layers' direction (docs/ARCHITECTURE.md); move the code or the include" >&2
  exit 1
fi
echo "layers.sh: every include and link follows acquisition -> geometry -> deform -> overlay -> node, session and sim beside, app on top"

if [[ $# -ge 1 ]]; then
  build=$(cd "$1" && pwd)
  out=$(mktemp -d)
  trap 'rm -rf "$out"' EXIT
  printf 'set(GRAPHVIZ_EXTERNAL_LIBS FALSE)\nset(GRAPHVIZ_GENERATE_PER_TARGET FALSE)\nset(GRAPHVIZ_GENERATE_DEPENDERS FALSE)\n' \
    > "$build/CMakeGraphVizOptions.cmake"
  cmake --graphviz="$out/evar.dot" "$build" > /dev/null
  rm -f "$build/CMakeGraphVizOptions.cmake"
  # node ids to names, then the edges between layer libraries (and the executable).
  awk -v layers="$(printf '%s ' "${target[@]}") evarnode" '
    BEGIN { n = split(layers, a, " "); for (i = 1; i <= n; i++) want[a[i]] = 1 }
    /\[ label = "/ { match($0, /"node[0-9]+"/); id = substr($0, RSTART, RLENGTH)
                     match($0, /label = "[^"]+"/); name[id] = substr($0, RSTART + 9, RLENGTH - 10) }
    / -> / && /"node/ { split($0, e, " -> "); from = e[1]; gsub(/^ +/, "", from)
                        match(e[2], /"node[0-9]+"/); to = substr(e[2], RSTART, RLENGTH)
                        style = ($0 ~ /dotted/) ? "  (private)" : ""
                        if (want[name[from]] && want[name[to]]) print "  " name[from] " -> " name[to] style }
  ' "$out/evar.dot" | sort
fi
