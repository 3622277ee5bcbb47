// kinserve playground: the "Closed form" panel. Shows ⁰Tₙ and each Aᵢ of the
// selected robot from GET /v1/robots/{name}/closed-form as MathML (rendered
// natively by the browser), with the symbols' values and the text forms.
// Server MathML is rebuilt element by element from a fixed list of MathML
// tags (no attributes, text through textContent), never assigned as HTML.
// Depends on api.js only.

import { closedForm, problemText } from './api.js';

const MATHML_NS = 'http://www.w3.org/1998/Math/MathML';
const TAGS = new Set(['math', 'mrow', 'mi', 'mn', 'mo', 'msub', 'mtable', 'mtr', 'mtd']);

/** A safe copy of a parsed MathML node, or null for anything unexpected. */
function rebuild(node) {
  if (node.nodeType === Node.TEXT_NODE) return document.createTextNode(node.textContent);
  if (node.nodeType !== Node.ELEMENT_NODE || !TAGS.has(node.localName)) return null;
  const out = document.createElementNS(MATHML_NS, node.localName);
  if (node.localName === 'math') out.setAttribute('display', 'block');
  for (const child of node.childNodes) {
    const c = rebuild(child);
    if (c) out.appendChild(c);
  }
  return out;
}

/** A MathML element from the server's string (or a text fallback). */
export function mathFrom(mathml, fallback) {
  const doc = new DOMParser().parseFromString(mathml, 'application/xml');
  const root = doc.documentElement;
  const built = root && root.localName === 'math' ? rebuild(root) : null;
  if (built) return built;
  const pre = document.createElement('pre');
  pre.textContent = fallback;
  return pre;
}

function textRows(text) {
  return text.map((row) => row.join('  |  ')).join('\n');
}

function sub(i) {
  return String(i).split('').map((d) => '₀₁₂₃₄₅₆₇₈₉'[Number(d)]).join('');
}

/**
 * Fills the panel for robot `name`; `isCurrent()` says whether it is still
 * selected, `signal` (optional) aborts the request when it no longer is.
 */
export async function showClosedForm(name, isCurrent, signal) {
  const box = document.getElementById('closed-form');
  const status = document.getElementById('closed-form-status');
  box.replaceChildren();
  status.textContent = 'Loading…';
  let cf;
  try {
    cf = await closedForm(name, signal);
  } catch (err) {
    if (isCurrent()) status.textContent = `No closed form: ${problemText(err)}`;
    return;
  }
  if (!isCurrent()) return;
  const n = cf.link_transforms.length;
  status.textContent = `⁰T${sub(n)} = A₁ ⋯ A${sub(n)} of the DH rows (${cf.convention} convention); FK = base · ⁰T${sub(n)} · tool. cI = cos(θ sum over I), sI = sin(…).`;
  const total = document.createElement('div');
  total.className = 'closed-form-math';
  total.id = 'closed-form-transform';
  total.appendChild(mathFrom(cf.transform.mathml, textRows(cf.transform.text)));
  box.appendChild(total);

  const symbols = Object.entries(cf.symbols);
  const sym = document.createElement('p');
  sym.className = 'muted';
  sym.id = 'closed-form-symbols';
  sym.textContent = symbols.length
    ? `Symbols (${cf.length_unit}): ` + symbols.map(([k, v]) => `${k} = ${v}`).join(', ')
    : 'No length symbols.';
  box.appendChild(sym);

  cf.link_transforms.forEach((m, i) => {
    const d = document.createElement('details');
    const s = document.createElement('summary');
    s.textContent = `A${sub(i + 1)} (row ${i + 1})`;
    d.append(s, mathFrom(m.mathml, textRows(m.text)));
    box.appendChild(d);
  });
  const t = document.createElement('details');
  const ts = document.createElement('summary');
  ts.textContent = `⁰T${sub(n)} as text (the grammar of the API)`;
  const pre = document.createElement('pre');
  pre.textContent = textRows(cf.transform.text);
  t.append(ts, pre);
  box.appendChild(t);
}
