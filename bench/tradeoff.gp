# The trade-off report's plot style, loaded before each plot's own commands:
#   gnuplot -e "out='docs/tradeoff/kepler_phase.svg'" bench/tradeoff.gp build/release/tradeoff/kepler_phase.gp
# Fixed size and fonts, no date: the same data give the same bytes.
set terminal svg size 720,480 fixed font "sans,12" background "white"
set termoption noenhanced
set output out
set grid xtics ytics lc rgb "#dddddd" dt 1
unset mxtics
unset mytics
set key below center horizontal maxcols 3 samplen 2 spacing 1.1
set pointsize 0.8
set style data linespoints
set linetype 1 lc rgb "#1b9e77" pt 7
set linetype 2 lc rgb "#d95f02" pt 5
set linetype 3 lc rgb "#7570b3" pt 9
set linetype 4 lc rgb "#e7298a" pt 11
set linetype 5 lc rgb "#66a61e" pt 13
set linetype 6 lc rgb "#a6761d" pt 4
