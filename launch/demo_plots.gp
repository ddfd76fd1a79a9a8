# SPDX-License-Identifier: MIT
# The demo's walk in four panels from the per-rank stats `occswitch render --stats` wrote:
#   gnuplot -e "stats='demo-out/stats.csv'; out='demo-out/walk.png'" launch/demo_plots.gp
# Rank 0 displays; ranks 1 and 2 (when there) are the occlusion switch and send the deltas.
# `smooth frequency` sums the rows of one frame: rank 0's series give the other ranks' rows 0, so
# the sum is rank 0's value (1/0 would break the lines).
set datafile separator ','
set datafile columnheaders
set terminal pngcairo size 1280,900 font 'sans,10' noenhanced
set output out
set grid ytics lc rgb '#dddddd'
set multiplot layout 2,2 title 'occswitch demo: the walk, frame by frame'

set title 'Display (rank 0): frame time and frames per second'
set xlabel 'frame'
set ylabel 'ms'
set y2label 'fps'
set y2tics
set ytics nomirror
set key top right
plot stats using (column('frame')):((column('rank') == 0 ? column('ms_total') + column('ms_draw') : 0)) smooth frequency with lines lw 2 title 'pipeline + draw ms', \
     '' using (column('frame')):((column('rank') == 0 ? column('ms_draw') : 0)) smooth frequency with lines title 'draw ms', \
     '' using (column('frame')):((column('rank') == 0 ? 1000.0 / (column('ms_total') + column('ms_draw')) : 0)) axes x1y2 smooth frequency with lines dt 2 title 'fps'

set title 'Occlusion culling against exact culling'
set key center right
set ylabel 'objects per frame'
set y2label 'culling accuracy %'
set y2range [0:105]
plot stats using (column('frame')):((column('rank') == 0 ? column('objects_in_frustum') : 0)) smooth frequency with lines title 'in the frustum', \
     '' using (column('frame')):((column('rank') == 0 ? column('exact_occluded') : 0)) smooth frequency with lines lw 2 title 'exactly occluded', \
     '' using (column('frame')):((column('rank') == 0 ? column('objects_occluded') : 0)) smooth frequency with lines lw 2 title 'culled by us', \
     '' using (column('frame')):((column('rank') == 0 ? column('false_culls') : 0)) smooth frequency with points pt 7 title 'false culls (must be 0)', \
     '' using (column('frame')):((column('rank') == 0 ? column('culling_accuracy') : 0)) axes x1y2 smooth frequency with lines dt 2 title 'accuracy %'
unset y2label
unset y2tics
set y2range [*:*]
set ytics mirror

set title 'Visible-set messages: deltas against full sets'
set ylabel 'bytes per frame (log)'
set logscale y
plot stats using (column('frame')):(column('bytes_delta')) smooth frequency with lines lw 2 title 'deltas sent (all ranks)', \
     '' using (column('frame')):(column('full_pvs_bytes')) smooth frequency with lines lw 2 title 'full sets would be'
unset logscale y

set title 'Camera-to-display latency and waiting'
set ylabel 'ms'
plot stats using (column('frame')):((column('rank') == 0 ? column('latency_ms') : 0)) smooth frequency with lines lw 2 title 'latency, camera sent to frame shown', \
     '' using (column('frame')):((column('rank') == 0 ? column('ms_wait') : 0)) smooth frequency with lines title 'display waits', \
     '' using (column('frame')):(column('rank') != 0 ? column('ms_wait') : 1/0) with points pt 7 ps 0.5 title 'switch ranks wait (each)'
unset multiplot
