//! The one place that calls `#[target_feature(enable = "avx2")]` code: [`avx2_dispatch!`]
//! (used by Batch-OMP's block coder, the stamping of sparse layers and, in
//! `relief-dictionary-learning`, the diverse atom pick).

/// Defines a function that runs an `#[inline(always)]` function compiled with AVX2 where the
/// CPU has it (checked at run time), and its baseline build everywhere else.
///
/// ```text
/// avx2_dispatch! {
///     /// Docs of the dispatcher.
///     vis fn name[generic parameters](arg: Type, ...) -> Ret => body;
/// }
/// ```
///
/// defines `vis fn name<generic parameters>(arg: Type, ...) -> Ret` (the `[...]` and `-> Ret`
/// are optional) whose result is `body(arg, ...)`. On x86-64 it holds a private twin of
/// `body` (the same call in a function marked `#[target_feature(enable = "avx2")]`) and calls
/// it when `is_x86_feature_detected!("avx2")` says the CPU has AVX2; on other targets, and on
/// x86-64 CPUs without AVX2, it calls `body` directly.
///
/// `body` must be `#[inline(always)]`, so that its code (and that of the `#[inline(always)]`
/// helpers it calls) is compiled into the twin with the wider vectors. AVX2 enables no FMA
/// and rustc contracts no multiply-add and reorders no floating-point sum, so both builds give
/// bit-identical results: the output never depends on the CPU.
///
/// # Safety argument
/// Calling a `#[target_feature]` function is unsafe only because the CPU must support the
/// enabled features. The twin is private to the generated function, its body is nothing but
/// the safe call `body(arg, ...)`, and the generated function calls it only right after
/// `is_x86_feature_detected!("avx2")` returned true. The generated function carries the
/// `#[allow(unsafe_code)]` (the workspace denies `unsafe_code`); its callers write no `unsafe`.
#[macro_export]
macro_rules! avx2_dispatch {
    (
        $(#[$meta:meta])*
        $vis:vis fn $name:ident $([$($gen:tt)*])? ($($arg:ident: $ty:ty),* $(,)?)
            $(-> $ret:ty)? => $body:path;
    ) => {
        $(#[$meta])*
        #[allow(unsafe_code)]
        $vis fn $name $(<$($gen)*>)? ($($arg: $ty),*) $(-> $ret)? {
            #[cfg(target_arch = "x86_64")]
            #[target_feature(enable = "avx2")]
            fn avx2 $(<$($gen)*>)? ($($arg: $ty),*) $(-> $ret)? {
                $body($($arg),*)
            }
            #[cfg(target_arch = "x86_64")]
            if ::std::arch::is_x86_feature_detected!("avx2") {
                // SAFETY: the CPU supports AVX2 (checked just above), the only requirement of
                // calling the `#[target_feature(enable = "avx2")]` function `avx2`, whose body
                // is the same safe call as the fallback below (see the macro's docs).
                return unsafe { avx2($($arg),*) };
            }
            $body($($arg),*)
        }
    };
}

#[cfg(test)]
mod tests {
    /// Sums in order (no reordering allowed, so the AVX2 build must match bit for bit).
    #[inline(always)]
    fn weighted_sum<T: Copy + Into<f64>>(x: &[T], w: &[f64], out: &mut f64) -> usize {
        let mut s = 0.0f64;
        for (a, b) in x.iter().zip(w) {
            s += (*a).into() * b;
        }
        *out = s;
        x.len().min(w.len())
    }

    crate::avx2_dispatch! {
        /// [`weighted_sum`] with AVX2 where the CPU has it.
        fn weighted_sum_dispatch[T: Copy + Into<f64>](x: &[T], w: &[f64], out: &mut f64)
            -> usize => weighted_sum;
    }

    #[inline(always)]
    fn scale(v: &mut [f32], by: f32) {
        for x in v {
            *x *= by;
        }
    }

    crate::avx2_dispatch! {
        fn scale_dispatch(v: &mut [f32], by: f32) => scale;
    }

    #[test]
    fn dispatch_gives_the_baseline_bits() {
        let x: Vec<f32> = (0..1000).map(|i| ((i * 37 % 101) as f32).sin()).collect();
        let w: Vec<f64> = (0..1000).map(|i| 1.0 / (1.0 + i as f64)).collect();
        let (mut a, mut b) = (0.0, 0.0);
        assert_eq!(weighted_sum_dispatch(&x, &w, &mut a), 1000);
        assert_eq!(weighted_sum(&x, &w, &mut b), 1000);
        assert_eq!(a.to_bits(), b.to_bits());
        let mut y = x.clone();
        scale_dispatch(&mut y, 1.7);
        let z: Vec<f32> = x.iter().map(|v| v * 1.7).collect();
        assert_eq!(y, z);
    }
}
