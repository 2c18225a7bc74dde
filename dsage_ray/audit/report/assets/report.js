
(function () {
  document.querySelectorAll('table.sortable').forEach(function (table) {
    var body = table.tBodies[0];
    table.tHead.addEventListener('click', function (event) {
      var button = event.target.closest('button.sort');
      if (!button) return;
      var th = button.closest('th'), col = th.cellIndex, numeric = th.classList.contains('num');
      // The first click sorts worst first: largest first where a larger value is worse (data-first).
      var first = th.dataset.first === 'descending' ? -1 : 1;
      var dir = th.getAttribute('aria-sort') === (first === 1 ? 'ascending' : 'descending') ? -first : first;
      table.tHead.querySelectorAll('th').forEach(function (h) { h.removeAttribute('aria-sort'); });
      th.setAttribute('aria-sort', dir === 1 ? 'ascending' : 'descending');
      var keyed = Array.from(body.rows, function (row) {
        var cell = row.cells[col], text = (cell.dataset.sort || cell.textContent).trim(), value = parseFloat(text);
        return [numeric ? (isNaN(value) ? -Infinity : value) : text.toLowerCase(), row];
      });
      keyed.sort(function (a, b) { return a[0] < b[0] ? -dir : a[0] > b[0] ? dir : 0; });
      body.append.apply(body, keyed.map(function (k) { return k[1]; }));
    });
  });
  // A scroll hint shows while the box after it is wider than the screen lets it be.
  function hints() {
    document.querySelectorAll('.scrollhint').forEach(function (hint) {
      var box = hint.nextElementSibling;
      hint.hidden = box.scrollWidth <= box.clientWidth + 1;
    });
  }
  window.addEventListener('resize', hints);
  hints();
  // Copy buttons: the button's own command (data-cmd), or the command beside it.
  document.addEventListener('click', function (event) {
    var button = event.target.closest('button.copy');
    if (!button) return;
    var code = button.previousElementSibling, text = button.dataset.cmd || code.textContent;
    var done = function () { button.textContent = 'copied'; };
    var fallback = function () {
      var area = document.createElement('textarea');
      area.value = text;
      document.body.appendChild(area);
      area.select();
      if (document.execCommand('copy')) done();
      area.remove();
    };
    if (navigator.clipboard) navigator.clipboard.writeText(text).then(done, fallback);
    else fallback();
  });
  var table = document.getElementById('levels');
  if (!table) return;
  var rows = Array.from(table.tBodies[0].rows), query = document.getElementById('query');
  // The text filter reads what a row shows (not its buttons) and its files' names.
  var texts = rows.map(function (row) {
    return Array.from(row.cells, function (cell) {
      return Array.from(cell.childNodes).filter(function (node) { return node.nodeName !== 'BUTTON'; })
        .map(function (node) { return node.textContent; }).join(' ') + ' ' +
        Array.from(cell.querySelectorAll('a'), function (a) { return a.getAttribute('href'); }).join(' ');
    }).join(' ').toLowerCase();
  });
  var never = document.getElementById('never'), regressed = document.getElementById('regressed');
  var lows = Array.from(document.querySelectorAll('input.lo'));
  var highs = Array.from(document.querySelectorAll('input.hi'));
  var shown = document.getElementById('shown');
  function values(inputs) { return inputs.map(function (i) { return parseFloat(i.value); }); }
  function apply() {
    var q = query.value.trim().toLowerCase(), count = 0, lo = values(lows), hi = values(highs);
    rows.forEach(function (row, r) {
      var m = row.dataset.m.split(' ').map(Number);
      var ok = (!q || texts[r].indexOf(q) >= 0) &&
               (!never.checked || Number(row.dataset.s) === 0) &&
               (!regressed || !regressed.checked || Number(row.dataset.r) > 0) &&
               m.every(function (v, j) { return !(v < lo[j]) && !(v > hi[j]); });
      row.hidden = !ok;
      if (ok) count++;
    });
    shown.textContent = count + ' of ' + rows.length + ' levels shown';
  }
  document.querySelectorAll('.filters input').forEach(function (input) { input.addEventListener('input', apply); });
  function clear() {
    document.querySelectorAll('.filters input').forEach(function (i) {
      if (i.type === 'checkbox') i.checked = false; else i.value = '';
    });
  }
  document.getElementById('reset').addEventListener('click', function () { clear(); apply(); });
  // A link to a level's row ("worst level") shows the row even when the filters hide it.
  document.addEventListener('click', function (event) {
    var link = event.target.closest('a[href^="#level-"]');
    var row = link && document.getElementById(link.getAttribute('href').slice(1));
    if (row && row.hidden) { clear(); apply(); }
  });
  // A region's button shows its levels alone: the other filters are cleared, and the range inputs take the
  // range the region table prints.
  document.querySelectorAll('button.region').forEach(function (button) {
    button.addEventListener('click', function () {
      var lo = button.dataset.lo.split(' '), hi = button.dataset.hi.split(' ');
      clear();
      lows.forEach(function (i, j) { i.value = lo[j]; });
      highs.forEach(function (i, j) { i.value = hi[j]; });
      apply();
      table.scrollIntoView();
    });
  });
  apply();
})();
