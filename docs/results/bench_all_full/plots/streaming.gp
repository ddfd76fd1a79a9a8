# streaming.png from the CSVs of `occswitch bench all`; run from the results folder: gnuplot plots/streaming.gp
set datafile separator ','
set terminal pngcairo size 960,560 font 'sans,10' noenhanced
set grid ytics lc rgb '#dddddd'
set key autotitle columnhead
set output 'plots/streaming.png'
set multiplot layout 1,2 title 'Streaming with coherence (SC), without (SnC) and none (NS): Peng & Cao 2012, Table 1'
set style data histograms
set style histogram rowstacked
set style fill solid 0.85 border -1
set boxwidth 0.7
set ylabel 'ms per frame'
set key top left
set xtics rotate by -30
label(row) = sprintf('%s %s', strcol(1), strcol(2))
plot 'streaming.csv' using (column('ms_stream_collect')):xtic(label(0)) title 'collect', \
     '' using (column('ms_defragment')) title 'defragment', '' using (column('ms_reform')) title 'reform'
set logscale y
set ylabel 'streamed triangles per frame (log)'
set style histogram clustered
plot 'streaming.csv' using (column('streamed_triangles_per_frame')):xtic(label(0)) title 'streamed triangles'
unset multiplot
