// The view's controls: fit, names, move/turn handles, enlarge, and the plan player (play/pause, step to
// the previous/next waypoint, a scrub slider, time and waypoint).

function button(text, title, onClick) {
  const b = document.createElement('button');
  b.type = 'button';
  b.textContent = text;
  b.title = title;
  b.addEventListener('click', onClick);
  return b;
}

export class Toolbar {
  constructor(container, view) {
    this.view = view;
    const bar = document.createElement('div');
    bar.className = 'ct-spatial-bar';
    this.home = button('Home', "back to the scene's own viewpoint", () => view.home());
    this.home.dataset.action = 'home';
    this.fit = button('Fit', 'frame the robot, the templates and the plan', () => view.fit());
    this.fit.dataset.action = 'fit';
    this.names = button('Names', 'show or hide names', () => view.setNamesVisible(!view.namesVisible));
    this.names.dataset.action = 'names';
    this.mode = button('Move', 'handles: move (translate) or turn (rotate)', () => view.registration.setMode(view.registration.mode === 'translate' ? 'rotate' : 'translate'));
    this.mode.dataset.action = 'mode';
    this.enlarge = button('Enlarge', 'fill the window with the view (Esc: back)', () => view.setEnlarged(!view.enlarged));
    this.enlarge.dataset.action = 'enlarge';
    this.accept = button('Accept', 'register the template where the camera located it (the cyan proposal)', () => view.accept());
    this.accept.dataset.action = 'accept-proposal';
    this.accept.hidden = true;
    const plan = document.createElement('div');
    plan.className = 'ct-spatial-plan';
    plan.hidden = true;
    this.prev = button('◀ Prev', 'previous waypoint', () => view.stepWaypoint(-1));
    this.prev.dataset.action = 'previous-waypoint';
    this.play = button('Play', 'play the planned motion', () => (view.player.playing ? view.player.pause() : view.player.play()));
    this.play.dataset.action = 'play';
    this.next = button('Next ▶', 'next waypoint', () => view.stepWaypoint(1));
    this.next.dataset.action = 'next-waypoint';
    this.slider = document.createElement('input');
    this.slider.type = 'range';
    this.slider.min = '0';
    this.slider.max = '1000';
    this.slider.value = '1000';
    this.slider.title = 'scrub through the planned motion';
    this.slider.addEventListener('input', () => {
      const fraction = Number(this.slider.value) / 1000; // read first: pausing redraws the slider
      view.player.pause();
      view.player.seek(fraction * view.player.duration);
    });
    this.readout = document.createElement('span');
    plan.append(this.prev, this.play, this.next, this.slider, this.readout);
    this.plan = plan;
    bar.append(this.home, this.fit, this.names, this.mode, this.accept, this.enlarge, plan);
    container.appendChild(bar);
    this.bar = bar;
  }

  refresh() {
    const v = this.view;
    this.names.setAttribute('aria-pressed', String(v.namesVisible));
    this.enlarge.setAttribute('aria-pressed', String(v.enlarged));
    this.enlarge.textContent = v.enlarged ? 'Restore' : 'Enlarge';
    this.mode.hidden = !v.registration.canAct;
    this.mode.textContent = v.registration.mode === 'translate' ? 'Move' : 'Turn';
    this.accept.hidden = !v.registration.canAct || v.registration.proposals.size === 0;
    const p = v.player;
    this.plan.hidden = !p.plan;
    if (!p.plan) return;
    this.play.textContent = p.playing ? 'Pause' : 'Play';
    this.play.title = p.playing ? 'pause' : 'play the planned motion';
    if (p.duration > 0) this.slider.value = String(Math.round((p.time / p.duration) * 1000));
    const w = p.currentWaypoint();
    this.readout.textContent = `${p.plan.instance} ${p.plan.trajectory} · ${p.time.toFixed(1)} / ${p.duration.toFixed(1)} s · ${w ? w.name : 'start'}`;
  }
}
