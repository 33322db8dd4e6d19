#!/usr/bin/env bash
# Makes docs/figures/ with the tool itself: an SVG animation of every example over one crank
# turn, a PNG still of the four-bar (headless Chromium), a plot of its analysis (gnuplot) and
# screenshots of kinegen view's page.
#   scripts/make_figures.sh [path/to/kinegen]   (default: build/codegen/kinegen)
set -euo pipefail
cd "$(dirname "$0")/.."
kinegen=${1:-build/codegen/kinegen}
out=docs/figures
mkdir -p "$out"
turn=6.283185307179586
for yaml in examples/*.yaml; do
  name=$(basename "$yaml" .yaml)
  "$kinegen" animate "$yaml" --t0 0 --t1 $turn --steps 120 --width 480 -o "$out/$name.svg"
done
"$kinegen" animate examples/four_bar.yaml --t0 0 --t1 $turn --steps 120 --frame 20 \
  --width 480 -o "$out/four_bar_frame.svg"
if command -v chromium >/dev/null; then
  size=$(sed -n 's/.*<svg[^>]* width="\([0-9]*\)" height="\([0-9]*\)".*/\1,\2/p' "$out/four_bar_frame.svg")
  profile=$(mktemp -d)
  chromium --headless --no-sandbox --disable-gpu --disable-quic --no-first-run \
    --disable-background-networking --disable-component-update --disable-sync \
    --hide-scrollbars --force-device-scale-factor=1 --user-data-dir="$profile" \
    --screenshot="$PWD/$out/four_bar_frame.png" --window-size="$size" \
    "file://$PWD/$out/four_bar_frame.svg" >/dev/null 2>&1
  rm -rf "$profile"
fi
rm -f "$out/four_bar_frame.svg"
csv=$(mktemp --suffix=.csv)
"$kinegen" analyze examples/four_bar.yaml --t0 0 --t1 $turn --steps 360 -o "$csv"
scripts/plot_analysis.sh "$csv" -o "$out/four_bar_analysis.png" --only coupler,rocker,P
rm -f "$csv"
# Forces: the balanced four-bar's reactions as arrows, and the motor torque over one turn (one
# second) with and without its balancing spring.
"$kinegen" animate examples/forces/four_bar_balanced.yaml --t0 0 --t1 1 --steps 120 --forces \
  --width 480 -o "$out/four_bar_balanced_forces.svg"
dir=$(mktemp -d)
"$kinegen" analyze examples/forces/four_bar_balanced.yaml --t0 0 --t1 1 --steps 360 --forces \
  -o "$dir/with_spring.csv"
"$kinegen" analyze examples/forces/four_bar_balanced.yaml --t0 0 --t1 1 --steps 360 --forces \
  --param k=0 -o "$dir/without_spring.csv"
scripts/plot_analysis.sh "$dir/with_spring.csv" "$dir/without_spring.csv" --columns motor.effort \
  --ylabel "motor torque (N m)" -o "$out/four_bar_balanced_torque.png"
rm -rf "$dir"
# The press: its motor torque over one cycle, the forming force over the last 20 mm of stroke.
dir=$(mktemp -d)
"$kinegen" analyze examples/forces/press.yaml --t0 0 --t1 1 --steps 720 --forces -o "$dir/press.csv"
scripts/plot_analysis.sh "$dir/press.csv" --columns motor.effort --ylabel "motor torque (N m)" \
  -o "$out/press_torque.png"
"$kinegen" animate examples/forces/press.yaml --t0 0 --t1 1 --steps 120 --forces --width 480 \
  -o "$out/press_forces.svg"
rm -rf "$dir"
# The planetary train: one turn of the carrier (4 s), the planet's tooth tracing its hypocycloid.
"$kinegen" animate examples/gears/planetary.yaml --t0 0 --t1 4 --steps 240 --width 480 \
  -o "$out/planetary.svg"
# The disc cam and its roller follower over one turn; the pin in the parabolic slot; the press
# on its measured motor table, with its reaction forces, over one cycle.
"$kinegen" animate examples/cams/disc_cam.yaml --t0 0 --t1 6.283185307179586 --steps 120 \
  --width 480 -o "$out/disc_cam.svg"
"$kinegen" animate examples/slots/slot.yaml --t0 0 --t1 6.283185307179586 --steps 120 \
  --width 480 -o "$out/slot.svg"
"$kinegen" animate examples/forces/table_press.yaml --t0 0 --t1 1 --steps 120 --forces \
  --width 480 -o "$out/table_press_forces.svg"
# Rack-and-pinion steering over one cycle of the wheel, lock to lock.
"$kinegen" animate examples/gears/steering.yaml --t0 0 --t1 6.283185307179586 --steps 120 \
  --width 480 -o "$out/steering.svg"
# The double wishbone corner's toe, camber, caster and kingpin inclination over wheel and rack
# travel.
scripts/plot_suspension.sh "$kinegen" examples/spatial/double_wishbone.yaml \
  "$out/suspension_double_wishbone.png" --rack rack
# kinegen view's page, in headless Chromium (playwright-core from viewer/node_modules: npm ci).
if [[ -d viewer/node_modules/playwright-core ]] && command -v node >/dev/null; then
  node viewer/screenshots.mjs "$kinegen"
fi
# The dynamics examples: simulated, plotted, the press and the four-bar animated.
scripts/make_dynamics_figures.sh "$kinegen"
