# scaling.png from the CSVs of `occswitch bench all`; run from the results folder: gnuplot plots/scaling.gp
set datafile separator ','
set terminal pngcairo size 960,560 font 'sans,10' noenhanced
set grid ytics lc rgb '#dddddd'
set key autotitle columnhead
set output 'plots/scaling.png'
set title 'Scene size against frame time (every stage but drawing) and peak memory'
set logscale xy
set autoscale xfix
set offsets graph 0.05, graph 0.05, 0, 0
set xlabel 'triangles in the scene'
set ylabel 'ms per frame (log)'
set y2label 'peak resident MB'
set y2tics
set ytics nomirror
set key top left
plot 'scaling.csv' using 3:(column('walk_oclod_ms')) with linespoints lw 2 pt 7 title 'walk, oc+lod', \
     '' using 3:(column('walk_lod_ms')) with linespoints lw 2 pt 5 title 'walk, lod', \
     '' using 3:(column('orbit_oclod_ms')) with linespoints lw 2 pt 9 title 'orbit, oc+lod', \
     '' using 3:(column('orbit_lod_ms')) with linespoints lw 2 pt 11 title 'orbit, lod', \
     '' using 3:(column('orbit_oclod_peak_mb')) axes x1y2 with linespoints dt 2 pt 6 title 'orbit, oc+lod: peak MB'
