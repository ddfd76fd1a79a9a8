# Bytes of visible-set messages per frame on the grid walk, 3 ranks (docs/results_switch.md).
#   gnuplot -e "out='bytes.png'" docs/results/switch_bytes.gp     (PNG; default: text plot)
if (!exists("out")) set terminal dumb 100 30; else set terminal pngcairo size 900,500; set output out
set datafile separator ","
set key autotitle columnhead top right
set logscale y
set xlabel "frame"
set ylabel "bytes per frame (all ranks)"
set title "occswitch: visible-set traffic, grid 10x10x10 walk, 3 ranks"
plot "docs/results/switch_grid_walk_bytes.csv" using 1:4 with lines, "" using 1:3 with lines, "" using 1:2 with lines
