# hierarchy.png from the CSVs of `occswitch bench all`; run from the results folder: gnuplot plots/hierarchy.gp
set datafile separator ','
set terminal pngcairo size 960,560 font 'sans,10' noenhanced
set grid ytics lc rgb '#dddddd'
set key autotitle columnhead
set output 'plots/hierarchy.png'
set datafile separator ','
set multiplot layout 1,2 title 'The hierarchy (issue 16): HLOD cuts against every object on its own, --lod error --tau 1'
set style data histograms
set style fill solid 0.8 border -1
set logscale y
set xtics rotate by -35 font ',8'
set key top left
label(row) = sprintf('%s %s %s', strcol(2), strcol(3), column(4) > 0 ? (column(5) > 0 ? 'hlod+vw' : 'hlod') : 'flat')
set ylabel 'per frame (log)'
plot 'hierarchy.csv' using (column('active_triangles')):xtic(label(0)) title 'triangles drawn', \
     '' using (column('items_drawn')) title 'items drawn'
unset logscale y
set ylabel 'PSNR dB against full detail'
plot 'hierarchy.csv' using (column('psnr_db')):xtic(label(0)) title 'PSNR' lc rgb '#4060c0'
unset multiplot
