// The launch's key leaving the page's address (sim/study/views/vr/web/address.js), run by node's test runner.
import assert from 'node:assert/strict';
import { test } from 'node:test';

import { forgetKey, withoutKey } from '../../sim/study/views/vr/web/address.js';

test('the address without the key keeps the rest of it', () => {
  assert.equal(withoutKey('https://10.0.0.5:8443/?key=s3cr3t', 'key'), 'https://10.0.0.5:8443/');
  assert.equal(withoutKey('http://localhost:8444/?a=1&key=s3cr3t#b', 'key'), 'http://localhost:8444/?a=1#b');
  assert.equal(withoutKey('https://[::1]:8443/?key=x&key=y', 'key'), 'https://[::1]:8443/');
  assert.equal(withoutKey('https://lab.example:8443/', 'key'), 'https://lab.example:8443/');
});

test("the tab's address is replaced, not added to, and only when it holds the key", () => {
  const replaced = [];
  const history = { state: { kept: true }, replaceState: (...call) => replaced.push(call) };
  forgetKey({ href: 'https://10.0.0.5:8443/?key=s3cr3t' }, history, 'key');
  assert.deepEqual(replaced, [[{ kept: true }, '', 'https://10.0.0.5:8443/']]);
  forgetKey({ href: 'https://10.0.0.5:8443/' }, history, 'key');
  assert.equal(replaced.length, 1);
});
