# Renders the synthetic experiment's CSVs (bitewise-synthetic) as PNG.
# Usage: gnuplot -e "dir='<csv dir>'; out='<png dir>'" plot_synthetic.gp
set datafile separator ','
set terminal pngcairo size 900,600 font ',11' noenhanced
set key top left
set xlabel 'round'
set grid
do for [d in '10 100'] {
  set output sprintf('%s/synthetic_dc%s.png', out, d)
  set ylabel 'cumulative regret (mean, band = 1 s.e.)'
  set title sprintf('Synthetic, d_c = %s, K = 10, d_p = 3', d)
  f = sprintf('%s/synthetic_dc%s.csv', dir, d)
  plot f every ::1 using 1:($2-$3):($2+$3) with filledcurves fs transparent solid 0.25 lc rgb '#d62728' notitle, \
       f every ::1 using 1:2 with lines lw 2 lc rgb '#d62728' title 'context-only LinUCB', \
       f every ::1 using 1:($4-$5):($4+$5) with filledcurves fs transparent solid 0.25 lc rgb '#1f77b4' notitle, \
       f every ::1 using 1:4 with lines lw 2 lc rgb '#1f77b4' title 'post hoc LinUCB', \
       f every ::1 using 1:($8-$9):($8+$9) with filledcurves fs transparent solid 0.25 lc rgb '#ff7f0e' notitle, \
       f every ::1 using 1:8 with lines lw 2 lc rgb '#ff7f0e' title 'poLinUCB'
}
set output sprintf('%s/synthetic_diff.png', out)
set title 'Synthetic: regret of context-only minus post hoc LinUCB (solid) and poLinUCB (dashed); band = 1 s.e., paired'
set ylabel 'cumulative regret difference'
f10 = sprintf('%s/synthetic_dc10.csv', dir)
f100 = sprintf('%s/synthetic_dc100.csv', dir)
plot f10 every ::1 using 1:($6-$7):($6+$7) with filledcurves fs transparent solid 0.25 lc rgb '#2ca02c' notitle, \
     f10 every ::1 using 1:6 with lines lw 2 lc rgb '#2ca02c' title 'd_c = 10', \
     f100 every ::1 using 1:($6-$7):($6+$7) with filledcurves fs transparent solid 0.25 lc rgb '#9467bd' notitle, \
     f100 every ::1 using 1:6 with lines lw 2 lc rgb '#9467bd' title 'd_c = 100', \
     f10 every ::1 using 1:10 with lines lw 2 dt 2 lc rgb '#2ca02c' title 'd_c = 10, poLinUCB', \
     f100 every ::1 using 1:10 with lines lw 2 dt 2 lc rgb '#9467bd' title 'd_c = 100, poLinUCB', \
     0 with lines lc rgb 'black' notitle
