#!/usr/bin/env bash
# Mutation check of the test oracles: breaks one push-constant builder or set-up at a time (a
# flipped sign, a wrong constant, a swapped flag), runs the tests of that technique family and
# reports which tests caught it. Every mutation must be caught by at least one test; the script
# exits non-zero otherwise. The tree is restored after each mutation (from a copy, so uncommitted
# work is safe). Slow — one incremental build per mutation, ~1 min each on 2 cores — so CI does
# not run it; the README says when it was last run and with what result.
#
#   bash tools/mutation-check.sh [FILTER]...   # only mutations whose name contains a FILTER
set -uo pipefail
cd "$(dirname "$0")/.."
export PATH="$HOME/.cargo/bin:$PATH"

# name | file | perl substitution (applied once, must change the file) | test files (space-separated)
mutations=(
  "filtered: far plane 1 % too far|src/techniques/filtered/config.rs|s/far: view.far,/far: view.far * 1.01,/|filtered filtered_properties"
  "filtered: perspective flag inverted|src/techniques/filtered/config.rs|s/LightProjection::Perspective \{ .. \}\) as i32/LightProjection::Orthographic { .. }) as i32/|filtered filtered_properties"
  "filtered: radius clamped to 1|src/techniques/filtered/config.rs|s/config.radius.min\(MAX_RADIUS\)/config.radius.min(1)/|filtered filtered_properties"
  "csm: group's first term off by one|src/techniques/filtered/config.rs|s/Mode::Csm => \(2 \* group \+ 1\)/Mode::Csm => (2 * group + 2)/|filtered filtered_properties"
  "csm: automatic offset negated|src/techniques/filtered/csm.rs|s/o if o < 0.0 => s.offset,/o if o < 0.0 => -s.offset,/|filtered filtered_properties"
  "csm: remap margin doubled|src/techniques/filtered/csm.rs|s/s.epsilon \+ REMAP_MARGIN/s.epsilon + 2.0 * REMAP_MARGIN/|filtered filtered_properties"
  "esm: exponent scaled by 0.9|src/techniques/filtered/esm.rs|s/params.f32\(\"exponent\"\)\?/0.9 * params.f32(\"exponent\")?/|filtered filtered_properties"
  "evsm: negative exponent halved|src/techniques/filtered/evsm.rs|s/params.f32\(\"exponent_negative\"\)\?/0.5 * params.f32(\"exponent_negative\")?/|filtered filtered_properties"
  "evsm: components 2 and 4 swapped|src/techniques/filtered/evsm.rs|s/<= 2 \{ 2 \} else \{ 4 \}/<= 2 { 4 } else { 2 }/|filtered filtered_properties"
  "msm: depth bias sign flipped|src/techniques/filtered/msm.rs|s/params.f32\(\"depth_bias\"\)\?/-params.f32(\"depth_bias\")?/|filtered filtered_properties"
  "savsm: perspective flag inverted|src/techniques/savsm.rs|s/LightProjection::Perspective \{ .. \}\) as i32/LightProjection::Orthographic { .. }) as i32/|savsm"
  "savsm: box one texel wider|src/techniques/savsm.rs|s/kernel: params.f32\(\"kernel\"\)\?,/kernel: params.f32(\"kernel\")? + 1.0,/|savsm"
  "reference: sun radius from the full diameter|src/reference/mod.rs|s/\(0.5 \* angular_diameter_deg\)/(angular_diameter_deg)/|reference reference_geometry"
  "reference: ray offset doubled|src/reference/mod.rs|s/offset: settings.ray_offset \* scale,/offset: 2.0 * settings.ray_offset * scale,/|reference reference_geometry"
  "average-maps: rect samples mirrored in v|src/passes/light_view.rs|s/v \* \(b - 0.5\)/v * (0.5 - b)/|gpu_vs_cpu average_maps"
  "pcf: kernel one wider|src/techniques/pcf.rs|s/let kernel = params.u32\(\"kernel\"\)\? as i32;/let kernel = params.u32(\"kernel\")? as i32 + 1;/|gpu_vs_cpu average_maps"
  "pcf-coverage: kernel floored at 1|src/techniques/pcf_coverage.rs|s/let kernel = params.f32\(\"kernel\"\)\?;/let kernel = params.f32(\"kernel\")?.max(1.0);/|pcf_family pcf_family_properties"
  "pcf-poisson: taps one fewer|src/techniques/pcf_poisson.rs|s/taps: disk_points.len\(\) as i32,/taps: disk_points.len() as i32 - 1,/|pcf_family pcf_family_properties"
  "pcss: light size halved|src/techniques/pcss.rs|s/light_size: light.size,/light_size: light.size * 0.5,/|pcss"
  "pcss: near plane 1 % farther|src/techniques/pcss.rs|s/near: setup.light_view.near,/near: setup.light_view.near * 1.01,/|pcss"
  "soft light: rect extent from one edge only|src/techniques/soft_light.rs|s/Vec2::new\(u.x.abs\(\) \+ v.x.abs\(\), u.y.abs\(\) \+ v.y.abs\(\)\)/Vec2::new(u.x.abs(), u.y.abs())/|pcss"
  "vssm: light size 10 % larger|src/techniques/vssm.rs|s/light_size: soft_light\(light, view, map_size\)\?.size,/light_size: soft_light(light, view, map_size)?.size * 1.1,/|vssm"
  "essm: light size 10 % larger|src/techniques/essm.rs|s/light_size: soft_light\(light, view, map_size\)\?.size,/light_size: soft_light(light, view, map_size)?.size * 1.1,/|essm"
  "shadow maps: constant and slope bias swapped|src/techniques/pcf.rs|s/constant: params.f32\(\"bias_constant\"\)\?,\n(\s*)slope: params.f32\(\"bias_slope\"\)\?,/constant: params.f32(\"bias_slope\")?,\n\$1slope: params.f32(\"bias_constant\")?,/|gpu_vs_cpu average_maps"
)

backup="$(mktemp -d)"
missed=0
printf '| mutation | caught by |\n|---|---|\n'
for m in "${mutations[@]}"; do
  IFS='|' read -r name file expr test <<<"$m"
  if [ $# -gt 0 ]; then
    wanted=0
    for f in "$@"; do [[ "$name" == *"$f"* ]] && wanted=1; done
    [ "$wanted" -eq 1 ] || continue
  fi
  cp "$file" "$backup/file"
  perl -0pi -e "$expr" "$file"
  if cmp -s "$file" "$backup/file"; then
    echo "| $name | **mutation did not apply** ($file) |"
    missed=$((missed + 1))
    continue
  fi
  log="$backup/log"
  targets=()
  for t in $test; do targets+=(--test "$t"); done
  cargo test --no-fail-fast "${targets[@]}" -- --test-threads 1 >"$log" 2>&1
  cp "$backup/file" "$file"
  failed=$(grep -E '^test .* FAILED$' "$log" | sed -E 's/^test (.*) \.\.\. FAILED$/\1/' | paste -sd, - | sed 's/,/, /g')
  if grep -q -E '^error(\[E[0-9]+\])?: could not compile|^error\[E' "$log"; then
    failed="(does not compile)"
  fi
  if [ -z "$failed" ]; then
    echo "| $name | **not caught** |"
    missed=$((missed + 1))
  else
    echo "| $name | \`$test\`: $failed |"
  fi
done
rm -rf "$backup"
if [ "$missed" -gt 0 ]; then
  echo "$missed mutation(s) not caught" >&2
  exit 1
fi
