// The right-hand avatar walks a 2.4 m square, round and round, once it has loaded.
const walker = document.getElementById('walker');
walker.addEventListener('load', () => {
  walker.followPath([[0, 0], [0, 2.4], [-2.4, 2.4], [-2.4, 0]], { loop: true });
});
// Errors show inside the element too; here they also go to the console.
for (const el of document.querySelectorAll('mm-avatar')) {
  el.addEventListener('error', (e) => console.warn(`${el.id}: ${e.detail.message}`));
}
