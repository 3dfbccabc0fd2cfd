// survey serve: keep the surveys being acquired on `/` up to date without
// reloading the page. Every few seconds (the body's data-refresh-ms) it reads
// /api/live and updates each survey's element (data-samples, the text, the
// progress bar), adds the surveys that started and removes those that ended.
'use strict';
(() => {
  const list = document.getElementById('live-list');
  const none = document.getElementById('live-none');
  const status = document.getElementById('live-status');
  const every = Number(document.body.dataset.refreshMs) || 1000;
  const span = (cls) => { const e = document.createElement('span'); e.className = cls; return e; };
  const duration = (s) => {
    if (s === null || s === undefined) return 'time left: not known yet';
    const m = Math.round(s / 60);
    return 'time left: ' + (m < 1 ? Math.round(s) + ' s' : m < 120 ? m + ' min' : (m / 60).toFixed(1) + ' h');
  };
  const element = (s) => {
    const e = document.createElement('div');
    e.className = 'live';
    e.id = 'live-' + s.uid;
    const a = document.createElement('a');
    a.href = '/surveys/' + encodeURIComponent(s.uid);
    a.textContent = 'survey ' + s.id + (s.check_points ? ': its check points' : '');
    const bar = document.createElement('progress');
    e.append(a, ' ', span('asset'), ' ', bar, ' ', span('done'), ', ', span('left'), ', ', span('faults'));
    return e;
  };
  const update = (e, s) => {
    e.dataset.samples = String(s.samples);
    e.querySelector('.asset').textContent = s.asset;
    const bar = e.querySelector('progress');
    if (s.planned_samples) { bar.max = s.planned_samples; bar.value = s.samples; }
    e.querySelector('.done').textContent =
      s.samples + (s.planned_samples ? ' of ' + s.planned_samples : '') + ' samples';
    e.querySelector('.left').textContent = duration(s.time_left_s);
    e.querySelector('.faults').textContent = s.faults + (s.faults === 1 ? ' fault' : ' faults') + ' met';
  };
  let refreshes = 0;
  const refresh = async () => {
    try {
      const r = await fetch('/api/live', {cache: 'no-store'});
      const doc = await r.json();
      if (!r.ok) throw new Error(doc.error || r.statusText);
      const seen = new Set();
      for (const s of doc.surveys) {
        seen.add('live-' + s.uid);
        let e = document.getElementById('live-' + s.uid);
        if (!e) { e = element(s); list.append(e); }
        update(e, s);
      }
      for (const e of [...list.children]) if (!seen.has(e.id)) e.remove();
      none.hidden = doc.surveys.length > 0;
      refreshes += 1;
      document.body.dataset.refreshes = String(refreshes);
      status.textContent = 'up to date at ' + new Date().toISOString().slice(11, 19) + ' UTC';
    } catch (err) {
      status.textContent = 'cannot refresh: ' + err.message;
    }
    setTimeout(refresh, every);
  };
  setTimeout(refresh, every);
})();
