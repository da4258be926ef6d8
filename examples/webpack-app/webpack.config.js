import HtmlWebpackPlugin from 'html-webpack-plugin';

export default {
  mode: 'production',
  entry: './src/index.js',
  output: { path: new URL('./dist', import.meta.url).pathname, filename: '[name].[contenthash].js', clean: true },
  plugins: [new HtmlWebpackPlugin({ template: './src/index.html' })],
  // The shipped database is 13 MB: large by design, and fetched only when an element uses it.
  performance: { hints: false },
};
