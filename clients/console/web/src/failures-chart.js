// Attempts and failures per meal as bars (uPlot on a canvas). The canvas is
// hidden from assistive technology: the table beside it carries the same
// numbers, and the figure's data-* attributes carry them for tests.

import uPlot from 'uplot';
import { h } from './dom.js';

const ATTEMPTS = '#1f5f99'; // 7.0:1 on white
const FAILURES = '#b3261e'; // 6.5:1 on white
const HEIGHT = 220;

export function createFailuresChart() {
  const canvasHolder = h('div', { className: 'chart-canvas', 'aria-hidden': 'true' });
  const legend = h(
    'p',
    { className: 'chart-legend', 'aria-hidden': 'true' },
    h('span', { className: 'swatch attempts' }),
    ' attempts ',
    h('span', { className: 'swatch failures' }),
    ' failures',
  );
  const root = h(
    'figure',
    { className: 'chart' },
    h(
      'figcaption',
      { id: 'chart-caption' },
      'Attempts and failures per meal, numbered in order (the table below has the same numbers and the ids)',
    ),
    legend,
    canvasHolder,
  );
  let plot = null;

  const resize = new ResizeObserver(() => {
    if (plot && canvasHolder.clientWidth > 0) plot.setSize({ width: canvasHolder.clientWidth, height: HEIGHT });
  });
  resize.observe(canvasHolder);

  /** meals: [{meal_id, attempts, failures}] in meal order. */
  function update(meals) {
    root.dataset.mealIds = JSON.stringify(meals.map((m) => m.meal_id));
    root.dataset.attempts = JSON.stringify(meals.map((m) => m.attempts));
    root.dataset.failures = JSON.stringify(meals.map((m) => m.failures));
    plot?.destroy();
    plot = null;
    if (meals.length === 0) return;

    const x = meals.map((_, i) => i + 1);
    const top = Math.max(1, ...meals.map((m) => m.attempts));
    const every = Math.ceil(meals.length / 12); // label at most 12 meals
    const bars = (align) => uPlot.paths.bars({ size: [0.4, 48], align });
    plot = new uPlot(
      {
        width: canvasHolder.clientWidth || 320,
        height: HEIGHT,
        legend: { show: false },
        cursor: { show: false },
        scales: {
          x: { time: false, range: [0.4, meals.length + 0.6] },
          y: { range: [0, top + 1] },
        },
        axes: [
          {
            splits: () => x,
            // Meal ids are long (meal-YYYYMMDD-HHMMSS): the axis numbers them.
            values: (_, splits) => splits.map((v) => ((v - 1) % every === 0 ? String(v) : '')),
            label: 'meal',
            stroke: '#222',
            grid: { show: false },
          },
          { stroke: '#222', label: 'bites', grid: { stroke: '#ddd' }, incrs: [1, 2, 5, 10, 20, 50, 100, 200, 500] },
        ],
        series: [
          {},
          { label: 'attempts', fill: ATTEMPTS, stroke: ATTEMPTS, paths: bars(-1), points: { show: false } },
          { label: 'failures', fill: FAILURES, stroke: FAILURES, paths: bars(1), points: { show: false } },
        ],
      },
      [x, meals.map((m) => m.attempts), meals.map((m) => m.failures)],
      canvasHolder,
    );
  }

  return { root, update };
}
