# fps.png from the CSVs of `occswitch bench all`; run from the results folder: gnuplot plots/fps.gp
set datafile separator ','
set terminal pngcairo size 960,560 font 'sans,10' noenhanced
set grid ytics lc rgb '#dddddd'
set key autotitle columnhead
set output 'plots/fps.png'
set multiplot layout 2,1 title 'Frames per second over the walk (Peng 2014, Figure 6)'
set ylabel 'fps'
set key outside right top vertical
set title 'engine grid'
plot 'fps_frames.csv' using 1:2 with lines lw 2 title 'oc+lod', '' using 1:3 with lines lw 2 title 'lod', \
     '' using 1:4 with lines lw 1 title 'full'
set title 'plant'
set xlabel 'frame'
plot 'fps_frames.csv' using 1:5 with lines lw 2 title 'oc+lod', '' using 1:6 with lines lw 2 title 'lod', \
     '' using 1:7 with lines lw 1 title 'full'
unset multiplot
