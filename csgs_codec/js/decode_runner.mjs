/**
 * Runs a decode plan (decode_plan.mjs) on lanes: this thread (LocalLane) or worker threads
 * (lane_client.mjs). A free lane takes the ready task of the earliest stage, largest
 * estimated cost first. When a task fails, only the tasks before it in the plan's error order
 * still start, and the error raised is the earliest in that order: the reference decoder's,
 * whichever lane found it.
 */

import { STAGES, accept, inputsFor, targetFor } from './decode_plan.mjs';
import { runTask } from './decode_tasks.mjs';

/** Runs tasks on this thread, writing the SH bands straight into their shared target. */
export class LocalLane {
  /** A task's outputs (a promise, so that the runner hands out other lanes' tasks first). */
  async run(plan, task, inputs) {
    await null;
    return runTask(plan.prep, task, inputs, targetFor(plan, task));
  }
}

/**
 * Run every task of ``plan``.
 * @param {object} plan from planDecode
 * @param {object[]} lanes LocalLane or RemoteLane instances (at least one)
 * @param {{onStage?: (stage: string, results: Map) => void, onTask?: (task: string,
 *   doneCost: number, totalCost: number) => void}} hooks onStage is told when every task of
 *   a stage and the stages before it is done ('first', 'color', 'semantic' in turn)
 * @returns {Promise<Map<string, object>>} every task's outputs
 */
export function runPlan(plan, lanes, { onStage = null, onTask = null } = {}) {
  const rank = new Map(plan.order.map((name, i) => [name, i]));
  const stageOf = (name) => STAGES.indexOf(plan.tasks.get(name).stage);
  const totalCost = plan.order.reduce((s, name) => s + plan.tasks.get(name).cost, 0);
  const results = new Map();
  const failures = new Map();
  const pending = new Set(plan.order);
  const idle = [...lanes];
  let running = 0;
  let doneCost = 0;
  let stagesTold = 0;
  for (const lane of lanes) if (lane.open) lane.open(plan);

  const ready = (name) => plan.tasks.get(name).needs.every((need) => results.has(need));
  const earliestFailure = () => Math.min(...[...failures.keys()].map((name) => rank.get(name)));
  const tellStages = () => {
    while (stagesTold < STAGES.length) {
      const stage = stagesTold;
      if (plan.order.some((name) => stageOf(name) <= stage && !results.has(name))) return;
      stagesTold++;
      if (onStage) onStage(STAGES[stage], results);
    }
  };

  return new Promise((resolve, reject) => {
    const finish = (name, lane, outputs, error) => {
      running--;
      idle.push(lane);
      if (error) {
        failures.set(name, error);
      } else {
        try {
          accept(plan, name, outputs, results);
          doneCost += plan.tasks.get(name).cost;
          if (onTask) onTask(name, doneCost, totalCost);
          if (!failures.size) tellStages();
        } catch (err) { // a hook's own error ends the decode
          failures.set(name, err);
        }
      }
      pump();
    };
    const pump = () => {
      const cutoff = failures.size ? earliestFailure() : Infinity;
      while (idle.length) {
        const candidates = [...pending].filter((name) => rank.get(name) < cutoff && ready(name));
        if (!candidates.length) break;
        candidates.sort((a, b) => stageOf(a) - stageOf(b) || plan.tasks.get(b).cost - plan.tasks.get(a).cost
          || rank.get(a) - rank.get(b));
        const name = candidates[0];
        pending.delete(name);
        const lane = idle.shift();
        running++;
        let inputs;
        try {
          inputs = inputsFor(plan, name, results);
        } catch (err) {
          queueMicrotask(() => finish(name, lane, null, err));
          continue;
        }
        lane.run(plan, name, inputs).then((outputs) => finish(name, lane, outputs, null),
          (err) => finish(name, lane, null, err ?? new Error(`task ${name} failed`)));
      }
      if (running) return;
      if (failures.size) {
        reject(failures.get(plan.order[earliestFailure()]));
      } else if (!pending.size) {
        resolve(results);
      } else {
        reject(new Error(`decode plan cannot go on: ${[...pending]} wait for tasks that never ran`));
      }
    };
    pump();
  });
}
