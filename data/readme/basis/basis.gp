# in this folder: gnuplot -e "set output 'basis.svg'" basis.gp
$t0 << EOD
25 0.262828
50 0.0972766
100 0.0491803
200 0.0197003
400 0.0057289
EOD
$s0 << EOD
5.46208 0.262828
14.341 0.0972766
28.0715 0.0491803
46.9537 0.0197003
92.8201 0.0057289
EOD
$b0 << EOD
250 0.0842685
500 0.0502025
1000 0.0349151
2000 0.0259995
4000 0.0197321
EOD
$t1 << EOD
25 0.10907
50 0.0522185
100 0.0248299
200 0.0125723
400 0.00514745
EOD
$s1 << EOD
8.25987 0.10907
14.4418 0.0522185
27.2674 0.0248299
59.4018 0.0125723
121.258 0.00514745
EOD
$b1 << EOD
250 0.0693061
500 0.0366483
1000 0.023809
2000 0.0179449
4000 0.0129701
EOD
$t2 << EOD
25 0.0834981
50 0.0371975
100 0.0159077
200 0.00598632
400 0.00204389
EOD
$s2 << EOD
10.0765 0.0834981
14.5841 0.0371975
23.4943 0.0159077
55.8819 0.00598632
117.05 0.00204389
EOD
$b2 << EOD
250 0.0677769
500 0.0328357
1000 0.0187425
2000 0.0112339
4000 0.00646823
EOD
$t3 << EOD
25 0.0614094
50 0.0411869
100 0.0273565
200 0.0190346
400 0.0135605
EOD
$s3 << EOD
11.9196 0.0614094
16.0769 0.0411869
23.1518 0.0273565
37.1011 0.0190346
54.3149 0.0135605
EOD
$b3 << EOD
250 0.0248487
500 0.0190346
1000 0.0190346
2000 0.0190346
4000 0.0190346
EOD
$t4 << EOD
25 0.204391
50 0.14623
100 0.0712313
200 0.0413608
400 0.0135605
EOD
$s4 << EOD
13.1574 0.204391
14.3092 0.14623
19.6619 0.0712313
30.2811 0.0413608
53.7635 0.0135605
EOD
$b4 << EOD
250 0.047574
500 0.0430774
1000 0.0413608
2000 0.0413608
4000 0.0413608
EOD
$t5 << EOD
25 0.246763
50 0.072915
100 0.0270418
200 0.0154096
400 0.0107066
EOD
$s5 << EOD
4.80453 0.246763
14.1798 0.072915
26.1789 0.0270418
52.1441 0.0154096
98.6704 0.0107066
EOD
$b5 << EOD
250 0.0489571
500 0.029393
1000 0.0189854
2000 0.0153682
4000 0.00923419
EOD
$t6 << EOD
25 0.0621455
50 0.0277461
100 0.0159395
200 0.0101162
400 0.00741984
EOD
$s6 << EOD
7.88198 0.0621455
13.6521 0.0277461
24.5022 0.0159395
50.5192 0.0101162
98.92 0.00741984
EOD
$b6 << EOD
250 0.0426012
500 0.0223853
1000 0.0133823
2000 0.00894476
4000 0.00419282
EOD
$t7 << EOD
25 0.0527813
50 0.024518
100 0.0137412
200 0.00931957
400 0.00712438
EOD
$s7 << EOD
8.37761 0.0527813
12.4936 0.024518
25.3523 0.0137412
49.0613 0.00931957
97.2631 0.00712438
EOD
$b7 << EOD
250 0.0423854
500 0.0216692
1000 0.0124431
2000 0.00808981
4000 0.00337531
EOD
set terminal svg size 1320,520 dynamic font 'sans,11' noenhanced
set logscale xy
set grid
set key bottom left font ',9'
set ylabel 'relative L2, geometric mean over 9 maps'
set multiplot layout 1,3 title 'Lighting bases on bunny.hlt, 1024 vertices'
set title 'error against terms'
set xlabel 'terms M (whole rows)'
plot $t0 using 1:2 with linespoints pt 4 ps 0.6 title 'haar', \
     $t1 using 1:2 with linespoints pt 5 ps 0.6 title 'haar-area', \
     $t2 using 1:2 with linespoints pt 6 ps 0.6 title 'haar-transport', \
     $t3 using 1:2 with linespoints pt 7 ps 0.6 title 'sh', \
     $t4 using 1:2 with linespoints pt 8 ps 0.6 title 'sh-nonlinear', \
     $t5 using 1:2 with linespoints pt 9 ps 0.6 title 'cube-haar', \
     $t6 using 1:2 with linespoints pt 10 ps 0.6 title 'cube-haar-area', \
     $t7 using 1:2 with linespoints pt 11 ps 0.6 title 'cube-haar-transport'
set title 'error against time'
set xlabel 'ms per lighting change, plain C (median over maps)'
plot $s0 using 1:2 with linespoints pt 4 ps 0.6 title 'haar', \
     $s1 using 1:2 with linespoints pt 5 ps 0.6 title 'haar-area', \
     $s2 using 1:2 with linespoints pt 6 ps 0.6 title 'haar-transport', \
     $s3 using 1:2 with linespoints pt 7 ps 0.6 title 'sh', \
     $s4 using 1:2 with linespoints pt 8 ps 0.6 title 'sh-nonlinear', \
     $s5 using 1:2 with linespoints pt 9 ps 0.6 title 'cube-haar', \
     $s6 using 1:2 with linespoints pt 10 ps 0.6 title 'cube-haar-area', \
     $s7 using 1:2 with linespoints pt 11 ps 0.6 title 'cube-haar-transport'
set title 'equal bytes, M = 200, against own exact'
set xlabel 'bytes per vertex'
plot $b0 using 1:2 with linespoints pt 4 ps 0.6 title 'haar', \
     $b1 using 1:2 with linespoints pt 5 ps 0.6 title 'haar-area', \
     $b2 using 1:2 with linespoints pt 6 ps 0.6 title 'haar-transport', \
     $b3 using 1:2 with linespoints pt 7 ps 0.6 title 'sh', \
     $b4 using 1:2 with linespoints pt 8 ps 0.6 title 'sh-nonlinear', \
     $b5 using 1:2 with linespoints pt 9 ps 0.6 title 'cube-haar', \
     $b6 using 1:2 with linespoints pt 10 ps 0.6 title 'cube-haar-area', \
     $b7 using 1:2 with linespoints pt 11 ps 0.6 title 'cube-haar-transport'
unset multiplot
