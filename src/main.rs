fn main() {
    println!("vmerge");
}
