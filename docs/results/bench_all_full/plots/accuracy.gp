# accuracy.png from the CSVs of `occswitch bench all`; run from the results folder: gnuplot plots/accuracy.gp
set datafile separator ','
set terminal pngcairo size 960,560 font 'sans,10' noenhanced
set grid ytics lc rgb '#dddddd'
set key autotitle columnhead
set output 'plots/accuracy.png'
set title 'Culling accuracy against exact culling (Peng 2014, Table 4) and false culls'
set xlabel 'frame'
set ylabel 'what we cull / what exact culling culls, %'
set yrange [0:105]
set y2label 'false culls'
set y2range [0:10]
set y2tics
set key bottom right
plot 'accuracy_frames.csv' using 1:2 with lines lw 2 title 'engine grid', \
     '' using 1:3 with lines lw 2 title 'plant', \
     '' using 1:4 axes x1y2 with points pt 7 title 'false culls, grid', \
     '' using 1:5 axes x1y2 with points pt 6 title 'false culls, plant'
