"""The paper's experiments: one module per figure (fig5, fig6, fig8, fig10), the study figures
fig7a, fig7b, table1 and fig9 (sweeps), all run through the sweep engine's study files
(nlos_cl/sweep/<name>.yaml) by `studies`."""
