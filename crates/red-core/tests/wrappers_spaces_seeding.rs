//! TimeLimit, RewardWrapper, Space and Seeder.

use ndarray::{Array1, ArrayView2};
use rand::{Rng, RngExt};
use red_core::seeding::{Seeder, Stream};
use red_core::{
    BoxSpace, ClippedActions, Env, Error, Info, LastAction, Result, RewardModel, RewardWrapper,
    Space, Step, TRUE_REWARD, TimeLimit, check_env,
};

/// Counts up by the action; terminates when the count reaches `end`; its
/// own reward is `10 * action`.
struct Counter {
    obs: Space,
    act: Space,
    count: f64,
    end: f64,
    running: bool,
}

impl Counter {
    fn new(end: f64) -> Self {
        Self {
            obs: Space::Box(BoxSpace::uniform(1, 0.0, 100.0)),
            act: Space::Box(BoxSpace::uniform(1, 0.0, 1.0)),
            count: 0.0,
            end,
            running: false,
        }
    }
}

impl Env for Counter {
    fn observation_space(&self) -> &Space {
        &self.obs
    }
    fn action_space(&self) -> &Space {
        &self.act
    }
    fn reset(&mut self, _seed: Option<u64>) -> Result<(Vec<f64>, Info)> {
        self.count = 0.0;
        self.running = true;
        Ok((vec![0.0], Info::new()))
    }
    fn step(&mut self, action: &[f64]) -> Result<Step> {
        self.act.check("action", action)?;
        if !self.running {
            return Err(Error::NeedsReset {
                reason: "counter stopped".into(),
            });
        }
        self.count += action[0];
        let terminated = self.count >= self.end;
        self.running = !terminated;
        Ok(Step {
            observation: vec![self.count],
            reward: 10.0 * action[0],
            terminated,
            truncated: false,
            info: Info::new(),
        })
    }
}

#[test]
fn time_limit_truncates_at_the_limit_only() {
    let mut env = TimeLimit::new(Counter::new(100.0), 4).unwrap();
    env.reset(Some(0)).unwrap();
    for k in 1..=4 {
        let s = env.step(&[1.0]).unwrap();
        assert!(!s.terminated);
        assert_eq!(s.truncated, k == 4, "step {k}");
        assert_eq!(env.elapsed(), k);
    }
    // The episode is over: no more steps until a reset, which restarts the
    // count.
    assert!(matches!(env.step(&[1.0]), Err(Error::NeedsReset { .. })));
    env.reset(None).unwrap();
    assert_eq!(env.elapsed(), 0);
    assert!(!env.step(&[1.0]).unwrap().truncated);
}

#[test]
fn termination_wins_over_truncation_on_the_same_step() {
    // The counter terminates on its 3rd step, exactly at the limit.
    let mut env = TimeLimit::new(Counter::new(3.0), 3).unwrap();
    env.reset(Some(0)).unwrap();
    env.step(&[1.0]).unwrap();
    env.step(&[1.0]).unwrap();
    let s = env.step(&[1.0]).unwrap();
    assert!(s.terminated);
    assert!(!s.truncated);
}

#[test]
fn time_limit_rejects_zero_and_steps_before_reset() {
    assert!(matches!(
        TimeLimit::new(Counter::new(1.0), 0),
        Err(Error::InvalidConfig { .. })
    ));
    let mut env = TimeLimit::new(Counter::new(1.0), 2).unwrap();
    let err = env.step(&[1.0]).unwrap_err();
    assert!(err.to_string().contains("before reset"), "{err}");
}

#[test]
fn inner_environments_never_set_truncated_themselves() {
    // Over a long run the bare counter never truncates: only TimeLimit does.
    let mut env = Counter::new(1e9);
    env.reset(Some(0)).unwrap();
    assert!((0..500).all(|_| !env.step(&[0.5]).unwrap().truncated));
}

/// r(s, a) = s - a, remembering every state it was asked about.
struct Diff;

impl RewardModel for Diff {
    fn rewards(
        &self,
        states: ArrayView2<'_, f64>,
        actions: ArrayView2<'_, f64>,
    ) -> Result<Array1<f64>> {
        Ok(&states.column(0) - &actions.column(0))
    }
}

#[test]
fn reward_wrapper_uses_the_state_the_action_was_taken_in() {
    let mut env = RewardWrapper::new(Counter::new(100.0), Diff);
    assert!(matches!(env.step(&[0.5]), Err(Error::NeedsReset { .. })));
    let (obs, _) = env.reset(Some(0)).unwrap();
    assert_eq!(obs, vec![0.0]);
    // s = 0, a = 0.25: r = -0.25; the true reward 2.5 is kept in info.
    let s1 = env.step(&[0.25]).unwrap();
    assert_eq!(s1.reward, -0.25);
    assert_eq!(s1.info.get(TRUE_REWARD), Some(2.5));
    assert_eq!(s1.observation, vec![0.25]);
    // s = 0.25 (the observation after the first step), a = 1.
    let s2 = env.step(&[1.0]).unwrap();
    assert_eq!(s2.reward, 0.25 - 1.0);
    assert_eq!(s2.info.get(TRUE_REWARD), Some(10.0));
    // A rejected action leaves the wrapper usable, with the same state.
    assert!(env.step(&[0.5, 0.5]).is_err());
    let s3 = env.step(&[0.5]).unwrap();
    assert_eq!(s3.reward, 1.25 - 0.5);
    // After reset the state is the reset observation again.
    env.reset(None).unwrap();
    assert_eq!(env.step(&[0.5]).unwrap().reward, -0.5);
}

#[test]
fn wrapped_environments_pass_the_checker() {
    let mut env = TimeLimit::new(RewardWrapper::new(Counter::new(5.0), Diff), 8).unwrap();
    let report = check_env(&mut env, 0, 100).unwrap();
    assert!(report.info_keys.contains(&TRUE_REWARD));
    assert!(report.terminated > 0 && report.truncated > 0, "{report}");
}

#[test]
fn last_action_is_appended_when_on_and_cleared_by_reset() {
    let mut off = LastAction::new(Counter::new(5.0), false).unwrap();
    assert!(!off.is_on());
    assert_eq!(
        off.observation_space(),
        &Space::Box(BoxSpace::uniform(1, 0.0, 100.0))
    );
    assert_eq!(off.reset(None).unwrap().0, vec![0.0]);
    assert_eq!(off.step(&[0.5]).unwrap().observation, vec![0.5]);

    let mut on = LastAction::new(Counter::new(5.0), true).unwrap();
    assert!(on.is_on());
    assert_eq!(
        on.observation_space(),
        &Space::Box(BoxSpace::new(vec![0.0, 0.0], vec![100.0, 1.0]).unwrap())
    );
    assert_eq!(on.reset(None).unwrap().0, vec![0.0, 0.0]);
    assert_eq!(on.step(&[0.5]).unwrap().observation, vec![0.5, 0.5]);
    let step = on.step(&[0.25]).unwrap();
    assert_eq!(step.observation, vec![0.75, 0.25]);
    assert_eq!(step.reward, 2.5);
    assert_eq!(on.reset(None).unwrap().0, vec![0.0, 0.0]);
    // A step the inner environment refuses is an error through the wrapper.
    assert!(on.step(&[3.0]).is_err());
    assert_eq!(on.step(&[1.0]).unwrap().observation, vec![1.0, 1.0]);
    let mut checked = TimeLimit::new(LastAction::new(Counter::new(5.0), true).unwrap(), 8).unwrap();
    check_env(&mut checked, 0, 50).unwrap();
}

#[test]
fn last_action_needs_box_spaces() {
    #[derive(Debug)]
    struct Pick(Space, Space);
    impl Env for Pick {
        fn observation_space(&self) -> &Space {
            &self.0
        }
        fn action_space(&self) -> &Space {
            &self.1
        }
        fn reset(&mut self, _seed: Option<u64>) -> Result<(Vec<f64>, Info)> {
            Ok((vec![0.0], Info::new()))
        }
        fn step(&mut self, _action: &[f64]) -> Result<Step> {
            unreachable!()
        }
    }
    let pick = Pick(
        Space::Box(BoxSpace::uniform(1, 0.0, 1.0)),
        Space::Discrete(3),
    );
    let e = LastAction::new(pick, true).unwrap_err().to_string();
    assert!(e.contains("box"), "{e}");
}

#[test]
fn box_space_contains_and_check() {
    let s = Space::Box(BoxSpace::new(vec![-1.0, 0.0], vec![1.0, f64::INFINITY]).unwrap());
    assert!(s.contains(&[0.0, 1e300]));
    assert!(s.contains(&[-1.0, 0.0]));
    assert!(!s.contains(&[1.5, 0.0]));
    assert!(!s.contains(&[0.0, -0.1]));
    assert!(!s.contains(&[0.0]));
    assert!(!s.contains(&[f64::NAN, 0.0]));
    assert!(!s.contains(&[0.0, f64::INFINITY]));
    assert!(matches!(
        s.check("a", &[0.0]),
        Err(Error::ShapeMismatch { .. })
    ));
    assert!(matches!(
        s.check("a", &[f64::NAN, 0.0]),
        Err(Error::NonFinite { .. })
    ));
    assert!(matches!(
        s.check("a", &[2.0, 0.0]),
        Err(Error::InvalidAction { .. })
    ));
    assert!(s.check("a", &[0.5, 3.0]).is_ok());
    assert!(BoxSpace::new(vec![1.0], vec![0.0]).is_err());
    assert!(BoxSpace::new(vec![f64::NAN], vec![0.0]).is_err());
    assert!(BoxSpace::new(vec![0.0], vec![]).is_err());
}

#[test]
fn discrete_space_contains_and_check() {
    let s = Space::Discrete(3);
    assert_eq!(s.dim(), 1);
    assert!(s.contains(&[0.0]) && s.contains(&[2.0]));
    assert!(!s.contains(&[3.0]) && !s.contains(&[-1.0]) && !s.contains(&[0.5]));
    assert!(!s.contains(&[0.0, 1.0]));
    assert!(s.check("a", &[1.0]).is_ok());
    assert!(s.check("a", &[1.5]).is_err());
    assert!(Space::Discrete(0).validate().is_err());
}

#[test]
fn samples_lie_in_the_space_and_cover_it() {
    let mut rng = Seeder::new(1).rng(Stream::Other(9));
    let spaces = [
        Space::Box(BoxSpace::new(vec![-2.0, 3.0, 0.0], vec![-1.0, 3.0, f64::INFINITY]).unwrap()),
        Space::Box(BoxSpace::uniform(2, f64::NEG_INFINITY, f64::INFINITY)),
        Space::Box(BoxSpace::uniform(1, f64::NEG_INFINITY, -10.0)),
        Space::Box(BoxSpace::uniform(1, -f64::MAX, f64::MAX)),
        Space::Discrete(4),
    ];
    for s in &spaces {
        s.validate().unwrap();
        for _ in 0..500 {
            let x = s.sample(&mut rng);
            assert!(s.contains(&x), "{x:?} outside {s:?}");
        }
    }
    let mut seen = [false; 4];
    for _ in 0..200 {
        seen[Space::Discrete(4).sample(&mut rng)[0] as usize] = true;
    }
    assert_eq!(seen, [true; 4]);
    let xs: Vec<f64> = (0..1000).map(|_| spaces[0].sample(&mut rng)[0]).collect();
    let mean = xs.iter().sum::<f64>() / xs.len() as f64;
    assert!((mean + 1.5).abs() < 0.05, "mean {mean} of U(-2, -1)");
}

#[test]
fn seeder_gives_the_same_stream_for_the_same_seed() {
    let a: Vec<u64> = {
        let mut r = Seeder::new(42).rng(Stream::Replay);
        (0..16).map(|_| r.next_u64()).collect()
    };
    let b: Vec<u64> = {
        let mut r = Seeder::new(42).rng(Stream::Replay);
        (0..16).map(|_| r.next_u64()).collect()
    };
    assert_eq!(a, b);
    assert_eq!(
        Seeder::new(42).derive(Stream::Env),
        Seeder::new(42).derive(Stream::Env)
    );
    assert_eq!(Seeder::new(42).seed(), 42);
}

#[test]
fn different_streams_and_seeds_differ() {
    let first = |seed: u64, s: Stream| -> Vec<u64> {
        let mut r = Seeder::new(seed).rng(s);
        (0..4).map(|_| r.next_u64()).collect()
    };
    let streams = [
        Stream::Env,
        Stream::Init,
        Stream::Exploration,
        Stream::Replay,
        Stream::Estimator,
        Stream::Eval,
        Stream::Demo,
        Stream::Other(0),
        Stream::Other(1),
    ];
    for (i, a) in streams.iter().enumerate() {
        for b in &streams[i + 1..] {
            assert_ne!(first(7, *a), first(7, *b), "{a:?} vs {b:?}");
        }
        assert_ne!(first(7, *a), first(8, *a));
    }
    // Drawing from one stream does not shift another.
    let seeder = Seeder::new(3);
    let mut env = seeder.rng(Stream::Env);
    let _: f64 = env.random();
    assert_eq!(first(3, Stream::Init), first(3, Stream::Init));
}

#[test]
fn box_space_clips_rows_into_its_bounds() {
    let b = BoxSpace::new(vec![-1.0, 0.0], vec![1.0, 2.0]).unwrap();
    let x = ndarray::array![[-3.0, 1.0], [0.5, 2.5], [1.0, -0.1]];
    let y = b.clip_rows(x.view()).unwrap();
    assert_eq!(y, ndarray::array![[-1.0, 1.0], [0.5, 2.0], [1.0, 0.0]]);
    let wrong = ndarray::Array2::<f64>::zeros((2, 3));
    assert!(matches!(
        b.clip_rows(wrong.view()),
        Err(Error::ShapeMismatch { .. })
    ));
}

/// Reward `-sum(a^2)`; records the actions of the last update.
struct Quadratic {
    seen: Vec<f64>,
}

impl RewardModel for Quadratic {
    fn rewards(&self, _s: ArrayView2<'_, f64>, a: ArrayView2<'_, f64>) -> Result<Array1<f64>> {
        Ok(a.rows().into_iter().map(|r| -r.dot(&r)).collect())
    }
    fn update(&mut self, _s: ArrayView2<'_, f64>, a: ArrayView2<'_, f64>) -> Result<()> {
        self.seen = a.iter().copied().collect();
        Ok(())
    }
    fn is_adaptive(&self) -> bool {
        true
    }
}

#[test]
fn clipped_actions_scores_and_updates_with_the_executed_actions() {
    let b = BoxSpace::uniform(2, -1.0, 1.0);
    let s = ndarray::Array2::<f64>::zeros((2, 1));
    let a = ndarray::array![[3.0, -0.5], [-2.0, 0.0]];
    let inner = Quadratic { seen: vec![] };
    let raw = inner.rewards(s.view(), a.view()).unwrap();
    assert_eq!(raw.to_vec(), vec![-9.25, -4.0]);
    let mut m = ClippedActions::new(inner, b);
    assert!(m.is_adaptive());
    assert_eq!(
        m.rewards(s.view(), a.view()).unwrap().to_vec(),
        vec![-1.25, -1.0]
    );
    m.update(s.view(), a.view()).unwrap();
    assert_eq!(m.into_inner().seen, vec![1.0, -0.5, -1.0, 0.0]);
}
