# latency.png from the CSVs of `occswitch bench all`; run from the results folder: gnuplot plots/latency.gp
set datafile separator ','
set terminal pngcairo size 960,560 font 'sans,10' noenhanced
set grid ytics lc rgb '#dddddd'
set key autotitle columnhead
set output 'plots/latency.png'
set title 'Camera-to-display latency and waiting per layout'
set style data histograms
set style histogram clustered gap 1
set style fill solid 0.85 border -1
set xlabel 'ranks'
set ylabel 'ms'
set key top left
plot 'latency.csv' using 3:xtic(1) title 'latency ms', '' using 4 title 'display waits ms/frame', \
     '' using 5 title 'other ranks wait ms/frame', '' using 6 title 'display frame ms'
