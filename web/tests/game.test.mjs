// Unit tests for the game mode's logic (game.js): colours, pushes, keys, and a player's
// round of the game against the messages a server sends.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import { ball, capped_push, colour_by_owner, Game, key_direction, max_speed, player_colour, start_spots } from '../src/game.js';

/** A page's side of the game: the commands it sent, with refs counting from 1. */
function game_with(options = {}) {
  const sent = [];
  const game = new Game({ send: (command) => (sent.push(command), sent.length), storage: options.storage ?? null, name: options.name ?? 'ann', random: () => 0 });
  return { game, sent };
}

/** A snapshot's columns as the page holds them (compact.js, to_snapshot). */
function snapshot(tick, bodies) {
  return {
    tick,
    count: bodies.length,
    id: Float64Array.from(bodies.map((b) => b.id)),
    owner: Float64Array.from(bodies.map((b) => b.owner)),
    position: Float64Array.from(bodies.flatMap((b) => b.position ?? [0, 0, 0])),
    velocity: Float64Array.from(bodies.flatMap((b) => b.velocity ?? [0, 0, 0])),
  };
}

/** A sessionStorage stand-in. */
function memory_storage() {
  const items = new Map();
  return { getItem: (k) => items.get(k) ?? null, setItem: (k, v) => items.set(k, String(v)), removeItem: (k) => items.delete(k), items };
}

const welcome = (client, extra = {}) => ({ type: 'welcome', client, room: 'game', ...extra });
const granted = { form: 'compact', rate: 30 };
const posts = [{ id: 1, owner: 0 }, { id: 2, owner: 0 }];

test('a player\'s colour depends on its id alone; neighbours differ; the scene\'s bodies are grey', () => {
  assert.deepEqual(player_colour(7), player_colour(7));
  const css = [1, 2, 3, 4, 5, 6].map((id) => player_colour(id).css);
  assert.equal(new Set(css).size, css.length);
  for (const c of css) assert.match(c, /^#[0-9a-f]{6}$/);
  const [r, g, b] = player_colour(0).rgb;
  assert.ok(Math.abs(r - g) < 0.05 && Math.abs(g - b) < 0.05, 'grey');
  const out = new Float32Array(9);
  const owners = new Map([[1, 0], [5, 3], [6, 4]]);
  colour_by_owner({ count: 3, id: Float64Array.from([1, 5, 6]) }, owners, out);
  assert.deepEqual(Array.from(out.slice(3, 6)), Array.from(Float32Array.from(player_colour(3).rgb)));
  assert.deepEqual(Array.from(out.slice(6, 9)), Array.from(Float32Array.from(player_colour(4).rgb)));
});

test('a push is kept in the pitch\'s plane and never takes the ball past the top speed', () => {
  assert.deepEqual(capped_push([0, 0, 0], [3, 4, 2]), [3, 4, 0]);
  const [x, y] = capped_push([0, 0, 0], [30, 40, 0]);
  assert.ok(Math.abs(Math.hypot(x, y) - max_speed) < 1e-9 && Math.abs(y / x - 4 / 3) < 1e-12, 'along the push, to the top speed');
  const v = [10, 0, 0];
  const dv = capped_push(v, [5, 0, 0]);
  assert.ok(Math.abs(v[0] + dv[0] - max_speed) < 1e-9);
  assert.deepEqual(capped_push([max_speed, 0, 0], [1, 0, 0]), [0, 0, 0], 'already at the top speed');
  assert.deepEqual(capped_push([max_speed, 0, 0], [-20, 0, 0]), [-20, 0, 0], 'a push that slows it, in full');
});

test('keys push as the camera sees the pitch', () => {
  const from_behind = [1, 0, -1]; // looking along +x, down
  assert.deepEqual(key_direction('ArrowUp', from_behind), [1, 0]);
  assert.deepEqual(key_direction('w', from_behind), [1, 0]);
  assert.deepEqual(key_direction('ArrowDown', from_behind), [-1, -0]);
  assert.deepEqual(key_direction('ArrowRight', from_behind), [0, -1]);
  assert.deepEqual(key_direction('a', from_behind), [-0, 1]);
  assert.deepEqual(key_direction('ArrowUp', [0, 0, -1]), [0, 1], 'looking straight down: up is +y');
  assert.equal(key_direction('x', from_behind), null);
});

test('the first hello names the player and asks for the goal events of balls; later ones only name it', () => {
  const { game } = game_with();
  assert.deepEqual(game.hello_fields(true, 'game'), { name: 'ann', events: { sensors: ['goal'], tags: ['ball'], kinds: ['entered'] } });
  assert.deepEqual(game.hello_fields(false, 'game'), { name: 'ann' });
  assert.deepEqual(game.rename('bob'), { type: 'hello', name: 'bob' });
  assert.equal(game.hello_fields(false, 'game').name, 'bob');
});

test('a tab without a name in its URL keeps the one it was given, and a random one the first time', () => {
  const storage = memory_storage();
  const first = new Game({ send: () => 1, storage, random: () => 0 });
  assert.match(first.name, /^otter 00$/);
  assert.equal(new Game({ send: () => 1, storage, random: () => 0.5 }).name, 'otter 00', 'the tab\'s name, after a reload');
  assert.equal(new Game({ send: () => 1, storage, name: 'cy' }).name, 'cy', 'the URL\'s wins');
});

test('once its hello is answered the page spawns one tagged ball on its start spot, and finds it in snapshots', () => {
  const { game, sent } = game_with();
  game.on_welcome(welcome(3));
  game.on_snapshot(snapshot(10, posts));
  assert.deepEqual(sent, [], 'not before the hello is answered: a resume may make it another player');
  game.on_welcome(welcome(3, { snapshots: granted }));
  game.on_snapshot(snapshot(11, posts));
  assert.deepEqual(sent, [{ type: 'spawn', body: { position: start_spots[2], radius: ball.radius, mass: ball.mass, tag: 'ball' } }]);
  game.on_snapshot(snapshot(12, posts));
  assert.equal(sent.length, 1, 'one spawn at a time');
  game.on_ack({ ref: 1, tick: 14, id: 9 });
  assert.equal(game.ball, 9);
  game.on_snapshot(snapshot(13, posts)); // older than the spawn's tick: the ball is not in it yet
  assert.equal(game.ball, 9);
  assert.equal(sent.length, 1);
  game.on_snapshot(snapshot(14, [...posts, { id: 9, owner: 3, velocity: [1, 2, 0] }]));
  assert.equal(game.ball, 9);
  assert.deepEqual(game.velocity, [1, 2, 0]);
  game.on_snapshot(snapshot(20, posts)); // gone (an admin removed it): a new one
  assert.equal(sent.length, 2);
  assert.equal(sent[1].type, 'spawn');
});

test('a start spot that is taken is passed over for the next; other refusals stop the spawning', () => {
  const { game, sent } = game_with();
  game.on_welcome(welcome(1, { snapshots: granted }));
  game.on_snapshot(snapshot(5, posts));
  game.on_error({ ref: 1, code: 'overlaps_body', message: 'taken' });
  game.on_snapshot(snapshot(6, posts));
  assert.deepEqual(sent.map((c) => c.body.position), [start_spots[0], start_spots[1]]);
  game.on_error({ ref: 2, code: 'rate_limited', message: 'slow down' });
  game.on_snapshot(snapshot(7, posts));
  assert.deepEqual(sent[2].body.position, start_spots[1], 'the same spot again');
  game.on_error({ ref: 3, code: 'room_full', message: 'full' });
  game.on_snapshot(snapshot(8, posts));
  assert.equal(sent.length, 3);
  assert.equal(game.failed, 'full');
});

test('a ball entering the goal scores for its owner on every page; its own page puts it back', () => {
  const mine = game_with();
  const theirs = game_with({ name: 'bob' });
  mine.game.on_welcome(welcome(1, { snapshots: granted }));
  theirs.game.on_welcome(welcome(2, { snapshots: granted }));
  const world = [...posts, { id: 5, owner: 1 }, { id: 6, owner: 2 }];
  for (const { game } of [mine, theirs]) game.on_snapshot(snapshot(30, world));
  assert.equal(mine.game.ball, 5);
  assert.equal(theirs.game.ball, 6);
  const goal = { type: 'event', tick: 31, time: 0.5, kind: 'entered', sensor: 'goal', body: 5, tag: 'ball' };
  assert.equal(mine.game.on_event(goal), 1);
  assert.equal(theirs.game.on_event(goal), 1);
  for (const { game } of [mine, theirs]) assert.deepEqual(Object.fromEntries(game.scores), { 1: 1 });
  assert.deepEqual(mine.sent.at(-1), { type: 'set', id: 5, position: start_spots[0], velocity: [0, 0, 0] });
  assert.equal(theirs.sent.length, 0, 'the other page leaves the ball alone');
  // A spot taken by then: the next one.
  mine.game.on_error({ ref: mine.sent.length, code: 'overlaps_body', message: 'taken' });
  assert.deepEqual(mine.sent.at(-1), { type: 'set', id: 5, position: start_spots[1], velocity: [0, 0, 0] });
  // What scores nothing: leaving, another sensor, a body of the scene's, one not known.
  for (const event of [{ ...goal, kind: 'left' }, { ...goal, sensor: 'centre' }, { ...goal, body: 1 }, { ...goal, body: 99 }]) {
    assert.equal(theirs.game.on_event(event), null);
  }
  const board = theirs.game.scoreboard([{ id: 1, name: 'ann' }, { id: 2, name: 'bob' }, { id: 4, name: null, away: true }]);
  assert.deepEqual(board.map((r) => [r.id, r.name, r.score, r.you, r.away]), [
    [1, 'ann', 1, false, false],
    [2, 'bob', 0, true, false],
    [4, 'player 4', 0, false, true],
  ]);
  assert.equal(board[0].colour, player_colour(1).css);
});

test('pushes go to the player\'s own ball as impulses, capped together before the next snapshot', () => {
  const { game, sent } = game_with();
  assert.equal(game.push([1, 0, 0]), null, 'no ball yet');
  game.on_welcome(welcome(1, { snapshots: granted }));
  game.on_snapshot(snapshot(3, [...posts, { id: 5, owner: 1 }]));
  game.push([8, 0, 0]);
  game.push([8, 0, 0]);
  assert.deepEqual(sent.map((c) => [c.type, c.id, c.impulse]), [['impulse', 5, [8 * ball.mass, 0, 0]], ['impulse', 5, [(max_speed - 8) * ball.mass, 0, 0]]]);
  game.brake();
  assert.deepEqual(sent.at(-1).impulse, [-max_speed * ball.mass, -0, 0]);
});

test('the resume token is kept per room and sent on a new socket; a resume gives the old ball back', () => {
  const storage = memory_storage();
  const first = game_with({ storage });
  first.game.on_welcome(welcome(3, { resume_token: 'a'.repeat(32) }));
  first.game.on_welcome(welcome(3, { resume_token: 'a'.repeat(32), snapshots: granted }));
  first.game.on_snapshot(snapshot(10, [...posts, { id: 8, owner: 3 }]));
  assert.equal(first.game.ball, 8);
  // The tab reloads: a new page, a new socket, a fresh player 9 until its hello's resume is answered.
  const again = game_with({ storage });
  assert.equal(again.game.hello_fields(true, 'game').resume, 'a'.repeat(32));
  again.game.on_welcome(welcome(9, { resume_token: 'b'.repeat(32) }));
  again.game.on_snapshot(snapshot(20, [...posts, { id: 8, owner: 3 }]));
  assert.deepEqual(again.sent, [], 'no ball of player 9\'s, and none spawned before the resume is answered');
  again.game.on_welcome(welcome(3, { resume_token: 'c'.repeat(32) }));
  again.game.on_welcome(welcome(3, { resume_token: 'c'.repeat(32), snapshots: granted }));
  again.game.on_snapshot(snapshot(21, [...posts, { id: 8, owner: 3 }]));
  assert.equal(again.game.ball, 8);
  assert.deepEqual(again.sent, []);
  assert.equal(storage.items.get('kugel.resume.game'), 'c'.repeat(32), 'the newest token');
  // A room that keeps nobody sends no token: none is kept.
  again.game.on_welcome(welcome(3, { snapshots: granted }));
  assert.equal(again.game.hello_fields(true, 'game').resume, undefined);
});
