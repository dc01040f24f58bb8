#!/usr/bin/env bash
# Regenerate every map image and plot the documentation (docs/) shows (except the live view's screenshot, docs/view/, taken by
# hand from a browser), with the commands that make them. Run from the repository root, venv active:
#     bash benchmarks/make_figures.sh [OUT]        # OUT: scratch folder for the runs (default out/readme)
# About 3 minutes on 2 cores. The figures land in docs/figures/ and docs/santos/.
set -euo pipefail
OUT="${1:-out/readme}"
rm -rf "$OUT"
mkdir -p "$OUT" docs/figures

# 1. One run's map and coverage figures, as `robotexp explore` writes them (docs/reference/results.md).
robotexp explore --world dense --method frontier --out "$OUT/frontier" --image-format png,svg
cp "$OUT"/frontier/dense_frontier_1_300mms_s0.png docs/figures/dense_frontier.png
cp "$OUT"/frontier/dense_frontier_1_300mms_s0.coverage.png docs/figures/dense_frontier.coverage.png

# 2. A potential field with its colour bar (BVP, log scale of 1 - potential).
robotexp explore --world dense --method bvp --max-time 120 --show potential --out "$OUT/bvp"
cp "$OUT"/bvp/dense_bvp_1_300mms_s0.png docs/figures/dense_bvp_potential.png

# 3. Odometry error: the path the robot believed beside the true one, without and with scan matching.
robotexp explore --world dense --method frontier --max-time 300 --odometry-error p3dx --localize none \
    --out "$OUT/odometry"
cp "$OUT"/odometry/dense_frontier_1_300mms_s0.png docs/figures/dense_frontier_p3dx_odometry.png
robotexp explore --world dense --method frontier --max-time 300 --odometry-error p3dx --localize scan-match \
    --out "$OUT/localized"
cp "$OUT"/localized/dense_frontier_1_300mms_s0.png docs/figures/dense_frontier_p3dx_scan_match.png

# 4. Santos's Table 8 box figures, from the campaign's records in docs/santos/results.jsonl (`robotexp figure`
#    draws coverage, path length and robot time too; docs/explanation/santos.md shows the visited cells).
robotexp figure docs/santos/results.jsonl -o "$OUT/santos-box" --format png,svg
cp "$OUT"/santos-box/box_visited_cells_{dense,sparse}.{png,svg} docs/santos/

# 5. The five meta-ga runs of that campaign in dense made again with its settings (seeds 0-4, 5 cm cells, his
#    search domain and stopping rule: near_frontier off, min_opening 0 as campaigns/santos.toml sets them,
#    pose 1, 300 mm/s; three of five give the recorded visited cells exactly, seeds 2 and 3 differ by 3-4 %),
#    their trajectories and coverage curves, as `robotexp campaign plot` of the whole campaign draws them.
for seed in 0 1 2 3 4; do
    robotexp explore --world dense --method meta-ga --pose 1 --seed "$seed" --cell 50 -p near_frontier=false -p min_opening=0 \
        --out "$OUT/santos-ga"
done
robotexp campaign plot "$OUT/santos-ga/results.jsonl" --out "$OUT/santos-ga/plots"
cp "$OUT"/santos-ga/plots/paths_dense_meta-ga.png docs/santos/paths_dense_meta-ga.png
cp "$OUT"/santos-ga/plots/coverage_dense.png docs/santos/coverage_dense_meta-ga.png
# 6. A team's map: four P3-DX with the burgard coordinator from dense's start 1, as the team study's first start
#    draws it (docs/how-to/teams.md; the study's coverage curves: benchmarks/studies/team_study.py --figures).
robotexp explore --world dense --team 4 --coordinator burgard --pose 1 --max-time 1800 --out "$OUT/team"
cp "$OUT"/team/dense_frontier-team4-burgard_1_300mms_s0.png docs/figures/teams_dense_burgard.png
echo "figures written: docs/figures/*.png docs/santos/*.png"
