// ESLint for the VR page and its node tests (launch_scripts/test.sh runs it from the repository's root with
// --config): the recommended rules, ES modules, the browser's globals for the page and node's for the tests.
import js from '@eslint/js';
import globals from 'globals';

export default [
  { ignores: ['**/node_modules/'] },
  js.configs.recommended,
  {
    files: ['**/*.js', '**/*.mjs'],
    languageOptions: { ecmaVersion: 2024, sourceType: 'module', globals: globals.browser },
  },
  {
    files: ['tests/js/**', '**/eslint.config.js'],
    languageOptions: { globals: globals.node },
  },
];
