#!/usr/bin/env bash
# Redraws the gallery (docs/gallery.md) and the tutorial's plot with `mechgen plot`.
set -euo pipefail
cd "$(dirname "$0")/.."
plot() { cargo run -q --release -- plot "$@"; }
plot examples/build-rs-user/planar_four_bar.toml --point M -o docs/planar-four-bar-M.svg
plot examples/four_bar.toml --point B -o docs/gallery/four_bar.svg
plot examples/rssr.toml --point B -o docs/gallery/rssr.svg
plot examples/slider_crank_5body.toml --point C -o docs/gallery/slider_crank_5body.svg
plot examples/spherical_joint.toml --point tip -o docs/gallery/spherical_joint.svg
plot examples/screw_joint.toml --point P -o docs/gallery/screw_joint.svg
plot examples/cylindrical_joint.toml --body sleeve -o docs/gallery/cylindrical_joint.svg
plot examples/prismatic_joint.toml --body slider -o docs/gallery/prismatic_joint.svg
plot examples/revolute_joint.toml --body bar --quantity omega -o docs/gallery/revolute_joint.svg
plot examples/universal_joint.toml --body bar --quantity omega -o docs/gallery/universal_joint.svg
for name in rotation_about_x rotation_about_y rotation_about_y_short static_body static_body_offset \
    translation_x translation_xy translation_xyz translation_y; do
    plot "examples/$name.toml" --point P -o "docs/gallery/$name.svg"
done
