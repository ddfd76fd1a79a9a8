# breakdown.png from the CSVs of `occswitch bench all`; run from the results folder: gnuplot plots/breakdown.gp
set datafile separator ','
set terminal pngcairo size 960,560 font 'sans,10' noenhanced
set grid ytics lc rgb '#dddddd'
set key autotitle columnhead
set output 'plots/breakdown.png'
set title 'Frame time per stage (Peng 2014, Table 3): mean ms per frame'
set style data histograms
set style histogram rowstacked
set style fill solid 0.85 border -1
set boxwidth 0.7
set key outside right
set ylabel 'ms per frame'
set xtics rotate by -30
plot for [c=4:10] 'breakdown.csv' using c:xtic(sprintf('%s %s', strcol(1), strcol(2))) title columnhead(c)
