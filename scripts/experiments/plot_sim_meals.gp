# Renders a simulated-meals CSV (bitewise-sim-meals) as two PNGs:
# <out>/<name>.png (cumulative failures per attempt, every learner, with
# one-standard-error bands, and the oracle and uniform-random expectations)
# and <out>/<name>_diff.png (context-only minus each post hoc variant,
# paired, with s.e. bands), poLinUCB's columns included.
# Usage: gnuplot -e "dir='<csv dir>'; out='<png dir>'; name='sim_meals'; \
#                    label='rho_c = 3'" plot_sim_meals.gp
if (!exists('name')) name = 'sim_meals'
if (!exists('label')) label = 'shipped defaults, lambda_c = 45.8'
set datafile separator ','
set terminal pngcairo size 900,600 font ',11' noenhanced
set key top left
set xlabel 'attempt (8 unseen foods x 8 attempts)'
set grid
f = sprintf('%s/%s.csv', dir, name)

set output sprintf('%s/%s.png', out, name)
set ylabel 'cumulative failures (mean, band = 1 s.e.)'
set title sprintf('Simulated meals: context-only vs post hoc LinUCB and poLinUCB (%s)', label)
plot f every ::1 using 1:($2-$3):($2+$3) with filledcurves fs transparent solid 0.2 lc rgb '#d62728' notitle, \
     f every ::1 using 1:2 with lines lw 2 lc rgb '#d62728' title 'context-only', \
     f every ::1 using 1:($4-$5):($4+$5) with filledcurves fs transparent solid 0.2 lc rgb '#1f77b4' notitle, \
     f every ::1 using 1:4 with lines lw 2 lc rgb '#1f77b4' title 'post hoc, log-probabilities', \
     f every ::1 using 1:($6-$7):($6+$7) with filledcurves fs transparent solid 0.2 lc rgb '#2ca02c' notitle, \
     f every ::1 using 1:6 with lines lw 2 lc rgb '#2ca02c' title 'post hoc, probabilities', \
     f every ::1 using 1:($8-$9):($8+$9) with filledcurves fs transparent solid 0.2 lc rgb '#9467bd' notitle, \
     f every ::1 using 1:8 with lines lw 2 lc rgb '#9467bd' title 'post hoc, one-hot class', \
     f every ::1 using 1:($24-$25):($24+$25) with filledcurves fs transparent solid 0.2 lc rgb '#ff7f0e' notitle, \
     f every ::1 using 1:24 with lines lw 2 lc rgb '#ff7f0e' title 'poLinUCB, log-probabilities', \
     f every ::1 using 1:17 with lines lw 1 dt 2 lc rgb 'gray40' title 'uniform random (expected)', \
     f every ::1 using 1:16 with lines lw 1 dt 2 lc rgb 'black' title 'best action (expected)'

set output sprintf('%s/%s_diff.png', out, name)
set ylabel 'failures of context-only minus post hoc'
set title sprintf('Simulated meals: paired difference, band = 1 s.e. (%s)', label)
plot f every ::1 using 1:($10-$11):($10+$11) with filledcurves fs transparent solid 0.2 lc rgb '#1f77b4' notitle, \
     f every ::1 using 1:10 with lines lw 2 lc rgb '#1f77b4' title 'log-probabilities', \
     f every ::1 using 1:($12-$13):($12+$13) with filledcurves fs transparent solid 0.2 lc rgb '#2ca02c' notitle, \
     f every ::1 using 1:12 with lines lw 2 lc rgb '#2ca02c' title 'probabilities', \
     f every ::1 using 1:($14-$15):($14+$15) with filledcurves fs transparent solid 0.2 lc rgb '#9467bd' notitle, \
     f every ::1 using 1:14 with lines lw 2 lc rgb '#9467bd' title 'one-hot class', \
     f every ::1 using 1:($26-$27):($26+$27) with filledcurves fs transparent solid 0.2 lc rgb '#ff7f0e' notitle, \
     f every ::1 using 1:26 with lines lw 2 lc rgb '#ff7f0e' title 'poLinUCB, log-probabilities', \
     0 with lines lc rgb 'black' notitle
