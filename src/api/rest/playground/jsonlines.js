// kinserve playground: find the line of a field path (`links[3].alpha`,
// `base.matrix[1][2]`, `name`) in JSON text as the user typed it.

/**
 * Walks JSON `text` and records, for every member and array element, the
 * 1-based line where it starts (the key for members, the value for elements).
 * Returns `{paths: Map<string, number>, error: null | {message, line, column}}`.
 */
export function jsonPathLines(text) {
  const paths = new Map();
  const lineStarts = [0];
  for (let i = 0; i < text.length; i++) if (text.charCodeAt(i) === 10) lineStarts.push(i + 1);
  const lineOf = (off) => {
    let lo = 0;
    let hi = lineStarts.length - 1;
    while (lo < hi) {
      const mid = (lo + hi + 1) >> 1;
      if (lineStarts[mid] <= off) lo = mid;
      else hi = mid - 1;
    }
    return lo + 1;
  };
  const colOf = (off) => off - lineStarts[lineOf(off) - 1] + 1;

  let pos = 0;
  const fail = (message) => {
    const e = new Error(message);
    e.offset = pos;
    throw e;
  };
  const ws = () => {
    while (pos < text.length) {
      const c = text[pos];
      if (c === ' ' || c === '\t' || c === '\n' || c === '\r') pos++;
      else break;
    }
  };
  const NUM = /-?(?:0|[1-9]\d*)(?:\.\d+)?(?:[eE][+-]?\d+)?/y;

  const str = () => {
    if (text[pos] !== '"') fail('expected a string');
    pos++;
    let out = '';
    while (pos < text.length) {
      const c = text[pos];
      if (c === '"') {
        pos++;
        return out;
      }
      if (c === '\\') {
        const n = text[pos + 1];
        const map = { '"': '"', '\\': '\\', '/': '/', b: '\b', f: '\f', n: '\n', r: '\r', t: '\t' };
        if (n in map) {
          out += map[n];
          pos += 2;
        } else if (n === 'u' && /^[0-9a-fA-F]{4}$/.test(text.slice(pos + 2, pos + 6))) {
          out += String.fromCharCode(parseInt(text.slice(pos + 2, pos + 6), 16));
          pos += 6;
        } else {
          fail('invalid escape in string');
        }
      } else if (c < ' ') {
        fail('control character in string');
      } else {
        out += c;
        pos++;
      }
    }
    fail('unterminated string');
    return out;
  };

  const value = (path, depth) => {
    if (depth > 200) fail('nesting too deep');
    ws();
    const c = text[pos];
    if (c === '{') {
      pos++;
      ws();
      if (text[pos] === '}') {
        pos++;
        return;
      }
      for (;;) {
        ws();
        const keyStart = pos;
        const key = str();
        const child = path ? `${path}.${key}` : key;
        if (!paths.has(child)) paths.set(child, lineOf(keyStart));
        ws();
        if (text[pos] !== ':') fail("expected ':' after the key");
        pos++;
        value(child, depth + 1);
        ws();
        if (text[pos] === ',') {
          pos++;
          continue;
        }
        if (text[pos] === '}') {
          pos++;
          return;
        }
        fail("expected ',' or '}'");
      }
    } else if (c === '[') {
      pos++;
      ws();
      if (text[pos] === ']') {
        pos++;
        return;
      }
      for (let i = 0; ; i++) {
        ws();
        const child = `${path}[${i}]`;
        paths.set(child, lineOf(pos));
        value(child, depth + 1);
        ws();
        if (text[pos] === ',') {
          pos++;
          continue;
        }
        if (text[pos] === ']') {
          pos++;
          return;
        }
        fail("expected ',' or ']'");
      }
    } else if (c === '"') {
      str();
    } else if (c === '-' || (c >= '0' && c <= '9')) {
      NUM.lastIndex = pos;
      const m = NUM.exec(text);
      if (!m) fail('invalid number');
      pos += m[0].length;
    } else if (text.startsWith('true', pos)) {
      pos += 4;
    } else if (text.startsWith('false', pos)) {
      pos += 5;
    } else if (text.startsWith('null', pos)) {
      pos += 4;
    } else if (pos >= text.length) {
      fail('unexpected end of input');
    } else {
      fail(`unexpected character '${c}'`);
    }
  };

  try {
    paths.set('', 1);
    value('', 0);
    ws();
    if (pos < text.length) fail('trailing characters after the JSON value');
    return { paths, error: null };
  } catch (e) {
    const off = Math.min(e.offset ?? pos, text.length);
    return { paths, error: { message: e.message, line: lineOf(off), column: colOf(off) } };
  }
}

/** Splits `links[3].alpha` into `['links', '[3]', 'alpha']`-style prefixes, longest first. */
function prefixes(path) {
  const out = [];
  let p = path;
  while (p) {
    out.push(p);
    const m = /(?:\.[^.[\]]*|\[\d+\])$/.exec(p);
    if (!m || m.index === 0) {
      p = '';
    } else {
      p = p.slice(0, m.index);
    }
  }
  return out;
}

/**
 * Line (1-based) for a server field path in `text`, or null. Falls back to the
 * nearest enclosing member (`links[3].alpha` missing → line of `links[3]`), and
 * to a "line N" quoted in `message` (serde syntax errors) when there is no path.
 */
export function lineForField(field, message, located) {
  const paths = located && located.paths ? located.paths : new Map();
  const f = String(field || '').replace(/^\$\.?/, '').replace(/^\//, '');
  if (f) {
    for (const p of prefixes(f)) if (paths.has(p)) return paths.get(p);
    // A wrapper prefix the editor does not have (e.g. `model.links[0]`)?
    const dot = f.indexOf('.');
    if (dot > 0) {
      for (const p of prefixes(f.slice(dot + 1))) if (paths.has(p)) return paths.get(p);
    }
  }
  const m = /\bline (\d+)/.exec(String(message || ''));
  if (m) return Number(m[1]);
  return null;
}
