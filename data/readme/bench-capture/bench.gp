# in this folder: gnuplot -e "set output 'bench.svg'" bench.gp
$s0 << EOD
4.16897 0.00576719 200
EOD
set terminal svg size 480,560 dynamic font 'sans,11' noenhanced
set logscale xy
set grid
set key bottom left font ',9'
set xlabel 'time per lighting change, OpenCL (ms)'
set ylabel 'relative L2 error vs exact discrete'
set multiplot layout 1,1 title 'Error against run time, transport selection, M = 200'
set title 'sqrt8.hlt'
plot $s0 using 1:2 with linespoints pt 7 ps 0.5 title 'sky'
unset multiplot

