# bytes.png from the CSVs of `occswitch bench all`; run from the results folder: gnuplot plots/bytes.gp
set datafile separator ','
set terminal pngcairo size 960,560 font 'sans,10' noenhanced
set grid ytics lc rgb '#dddddd'
set key autotitle columnhead
set output 'plots/bytes.png'
set title 'Visible-set bytes per frame (Govindaraju et al. 2003, Figure 3)'
set xlabel 'frame'
set ylabel 'bytes per frame (log)'
set logscale y
set key top right
plot 'bytes_frames.csv' using 1:($2 > 0 ? $2 : 1/0) with lines lw 2 title 'engine grid: deltas', \
     '' using 1:($3 > 0 ? $3 : 1/0) with lines lw 2 title 'engine grid: full sets (--no-deltas)', \
     '' using 1:($5 > 0 ? $5 : 1/0) with lines lw 2 title 'plant: deltas', \
     '' using 1:($6 > 0 ? $6 : 1/0) with lines lw 2 title 'plant: full sets (--no-deltas)'
