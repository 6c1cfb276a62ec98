# Renders the MNIST experiment's CSVs (bitewise-mnist) as PNG.
# Usage: gnuplot -e "dir='<csv dir>'; out='<png dir>'" plot_mnist.gp
set datafile separator ','
set terminal pngcairo size 900,600 font ',11' noenhanced
set grid
set xlabel 'round of uniform exploration'
set ylabel 'test MSE (mean, band = 1 s.e.)'
set key top right
set output sprintf('%s/mnist_learning.png', out)
set title 'MNIST learning speed (PCA-200 contexts, K = 10, d_p = 10)'
f = sprintf('%s/mnist_learning.csv', dir)
plot f every ::1 using 1:($2-$3):($2+$3) with filledcurves fs transparent solid 0.25 lc rgb '#d62728' notitle, \
     f every ::1 using 1:2 with lines lw 2 lc rgb '#d62728' title 'context model, context-only', \
     f every ::1 using 1:($4-$5):($4+$5) with filledcurves fs transparent solid 0.25 lc rgb '#1f77b4' notitle, \
     f every ::1 using 1:4 with lines lw 2 lc rgb '#1f77b4' title 'context model, post hoc', \
     f every ::1 using 1:6 with lines lw 2 dt 2 lc rgb '#2ca02c' title 'post hoc model', \
     f every ::1 using 1:8 with lines lw 2 dt 3 lc rgb 'black' title 'best linear (full feedback)'
set output sprintf('%s/mnist_regret.png', out)
set title 'MNIST cumulative regret of LinUCB over test digits'
set xlabel 'round'
set ylabel 'cumulative regret = mistakes (mean, band = 1 s.e.)'
set key top left
f = sprintf('%s/mnist_regret.csv', dir)
plot f every ::1 using 1:($2-$3):($2+$3) with filledcurves fs transparent solid 0.25 lc rgb '#d62728' notitle, \
     f every ::1 using 1:2 with lines lw 2 lc rgb '#d62728' title 'context-only LinUCB', \
     f every ::1 using 1:($4-$5):($4+$5) with filledcurves fs transparent solid 0.25 lc rgb '#1f77b4' notitle, \
     f every ::1 using 1:4 with lines lw 2 lc rgb '#1f77b4' title 'post hoc LinUCB', \
     f every ::1 using 1:($8-$9):($8+$9) with filledcurves fs transparent solid 0.25 lc rgb '#ff7f0e' notitle, \
     f every ::1 using 1:8 with lines lw 2 lc rgb '#ff7f0e' title 'poLinUCB'
